"""The garment catalogue: an SQLite index plus a directory of prepared arrays per garment.

Layout under ``data_dir``::

    catalogue.sqlite            index: one row per catalogue entry (GarmentMeta + preparation params)
    sources/<sha256>.<ext>      the uploaded file, kept so that other simplification degrees can be made
    models/<key>/               model.npz + meta.json + prepared.json (GarmentModel.save); key = id for the
                                entry itself, id-B<b> for a variant with another simplification degree;
                                a model of another PREPARATION_VERSION is prepared again from its source
    tmp/                        work directories; anything here is a leftover of a crash

An entry's id is a short hash of the file's sha256 and the preprocessing parameters (units,
simplification, density), so the same file with the same parameters is the same entry (idempotent).
Writes are atomic: the model is prepared in ``tmp/``, moved into place with ``os.replace`` (atomic on one
file system), and only then is the row inserted in a transaction. A crash leaves no row, and at worst a
complete model directory without a row, which the next ingestion of that file adopts. Two ingestions at
once (threads or processes) race only on the rename and the ``INSERT OR IGNORE``; both end with the same
single entry.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import sqlite3
import threading
import time
import uuid
from collections import OrderedDict
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from tryon.garment.ingest import GarmentError, check_readable, file_extension, load_garment
from tryon.garment.model import GarmentMeta, GarmentModel
from tryon.garment.prepare import DEFAULT_DENSITY, DEFAULT_SIMPLIFICATION, prepare
from tryon.garment.sizes import check_labels, check_size, check_style, parse_chart, size_order

CATEGORIES = ("top", "bottom", "dress")
# Words in a file name that tell its category ("auto"), matched anywhere in the name, any case. A dress,
# or a file with a top word and a bottom word (an outfit: a shirt and trousers in one file), is "dress":
# the sim aligns each piece of a file by its own kind (sim/pieces.py), but a file catalogued as a bottom
# is one bottom whatever its pieces. "short" before "sleeve" is a short-sleeved top, not shorts.
DRESS_WORDS = r"dress|gown|robe|outfit|suit|jumpsuit|overall"
BOTTOM_WORDS = r"skirt|trouser|pant|short(?![-_ ]?sleeve)|jean|legging|bottom|chino|jogger|culotte"
TOP_WORDS = r"shirt|tee|top|blouse|polo|sweater|jacket|hoodie|sleeve|cardigan|coat|vest|tunic|pullover|blazer"
# An entry's own words, which ``Catalogue.update`` changes (the file and its preparation make the rest).
WORDS = ("name", "size", "style", "chart")
# Longest display name (the upload form's limit).
NAME_MAX_CHARS = 200
# Prepared models kept in memory per process (a model of 5,000 vertices is ~1 MB).
MODEL_CACHE_SIZE = 16
# SQLite waits this long (s) for another writer's transaction before giving up.
SQLITE_TIMEOUT_S = 30.0
# Work directories older than this (s) are leftovers of a crashed ingestion and are removed.
STALE_TMP_S = 3600.0

_SCHEMA = """
CREATE TABLE IF NOT EXISTS garments (
    id TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    category TEXT NOT NULL,
    size TEXT,
    style TEXT,
    chart TEXT,
    units TEXT NOT NULL,
    requested_units TEXT NOT NULL,
    simplification REAL NOT NULL,
    density REAL NOT NULL,
    source_sha256 TEXT NOT NULL,
    source_ext TEXT NOT NULL,
    meta TEXT NOT NULL,
    created REAL NOT NULL
)
"""
# Columns added after the first catalogues were written: (name, SQL type). A catalogue.sqlite without them
# gains them when opened (NULL: no style, no chart), so existing data directories keep working.
_ADDED_COLUMNS = (("style", "TEXT"), ("chart", "TEXT"))


def guess_category(filename: str) -> str | None:
    """top | bottom | dress from the words in a file name (see ``DRESS_WORDS``), or None when the name
    has none of them."""
    has = lambda pattern: re.search(pattern, filename, re.IGNORECASE) is not None  # noqa: E731
    if has(DRESS_WORDS) or (has(TOP_WORDS) and has(BOTTOM_WORDS)):
        return "dress"
    if has(BOTTOM_WORDS):
        return "bottom"
    return "top" if has(TOP_WORDS) else None


def resolve_category(category: str, filename: str) -> str:
    """``category`` as given, or for ``auto`` the one the file name tells (``guess_category``).
    GarmentError (422) for an unknown category, or ``auto`` with a file name that tells none."""
    if category == "auto":
        guessed = guess_category(filename)
        if guessed is None:
            raise GarmentError(
                f"the file name {filename!r} gives no hint of the category (no word such as shirt, skirt, "
                f"trousers or dress): choose one of {', '.join(CATEGORIES)}"
            )
        return guessed
    if category not in CATEGORIES:
        raise GarmentError(f"category must be one of {', '.join(CATEGORIES)} or auto, not {category!r}")
    return category


def entry_id(sha256: str, units: str, simplification: float, density: float) -> str:
    """12 hex digits naming (file content, preprocessing parameters)."""
    key = f"{sha256}|units={units}|B={simplification:.4f}|density={density:.5f}"
    return hashlib.sha256(key.encode()).hexdigest()[:12]


@dataclass(frozen=True)
class Preparation:
    """What preparing one new entry needs, as plain data (it may travel to another process or machine, see
    ``tryon ingest --ray``): the file's bytes and name, its units, the entry's meta so far, the fabric's
    density (kg/m^2) and the largest mesh taken (faces)."""

    data: bytes
    filename: str
    units: str
    meta: GarmentMeta
    density: float
    max_faces: int


def prepare_model(job: Preparation) -> GarmentModel:
    """The middle of an ingestion, anywhere: load, clean and prepare the mesh (the costly part, CPU only;
    no catalogue needed). GarmentError if the file is refused. Deterministic: the same job gives the same
    arrays wherever it runs."""
    mesh = load_garment(job.data, job.filename, job.units, job.max_faces)
    m = job.meta
    return prepare(mesh, id=m.id, name=m.name, category=m.category, size=m.size, source_sha256=m.source_sha256,
                   source_name=m.source_name, simplification=m.simplification, density=job.density)


@dataclass(frozen=True)
class IngestPlan:
    """One ingestion between ``Catalogue.plan_ingest`` and ``Catalogue.add_prepared``: the entry's id and
    row fields, the file's bytes, and either the existing entry or the preparation a new one needs."""

    gid: str
    name: str
    category: str
    size: str | None
    units: str
    simplify: float
    density: float
    sha256: str
    ext: str
    style: str | None
    chart: dict | None
    data: bytes
    existing: GarmentMeta | None = None
    preparation: Preparation | None = None


def _write_ahead(db: sqlite3.Connection) -> None:
    """Switch the index to write-ahead logging. Two processes opening a new catalogue at once both ask; the
    switch needs the database to itself and sqlite answers "database is locked" at once instead of waiting
    for the connection's timeout, so it is asked again for up to SQLITE_TIMEOUT_S."""
    deadline = time.monotonic() + SQLITE_TIMEOUT_S
    while True:
        try:
            db.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.05)


class Catalogue:
    """Garments prepared once and cached under ``data_dir`` (see the module docstring)."""

    def __init__(self, data_dir: Path | str, cache_size: int = MODEL_CACHE_SIZE):
        self.data_dir = Path(data_dir)
        self.db_path = self.data_dir / "catalogue.sqlite"
        self.sources = self.data_dir / "sources"
        self.models = self.data_dir / "models"
        self.tmp = self.data_dir / "tmp"
        for d in (self.sources, self.models, self.tmp):
            d.mkdir(parents=True, exist_ok=True)
        self._cache: OrderedDict[str, GarmentModel] = OrderedDict()
        self._cache_size = cache_size
        self._lock = threading.Lock()
        with self._connect() as db:
            _write_ahead(db)
            db.execute(_SCHEMA)
            have = {r[1] for r in db.execute("PRAGMA table_info(garments)")}
            for column, kind in _ADDED_COLUMNS:
                if column not in have:
                    try:
                        db.execute(f"ALTER TABLE garments ADD COLUMN {column} {kind}")
                    except sqlite3.OperationalError:  # another process added it first
                        pass
        self._remove_stale_tmp()

    # --- reading ----------------------------------------------------------------------------------

    def list(self) -> list[GarmentMeta]:
        """Every entry, oldest first."""
        with self._connect() as db:
            rows = db.execute("SELECT * FROM garments ORDER BY created, id").fetchall()
        return [_meta(r) for r in rows]

    def get(self, garment_id: str) -> GarmentMeta | None:
        """The entry's meta, or None if there is no such id."""
        with self._connect() as db:
            row = db.execute("SELECT * FROM garments WHERE id = ?", (garment_id,)).fetchone()
        return _meta(row) if row else None

    def styles(self) -> dict[str, list[GarmentMeta]]:
        """Every style and its entries in size order (``sizes.size_order``), styles in the order their
        first entry was added."""
        out: dict[str, list[GarmentMeta]] = {}
        for meta in self.list():
            if meta.style is not None:
                out.setdefault(meta.style, []).append(meta)
        return {style: [entries[i] for i in size_order([m.size or "" for m in entries])]
                for style, entries in out.items()}

    def style(self, style: str) -> list[GarmentMeta]:
        """The entries of one style in size order; empty if there is no such style."""
        return self.styles().get(style, [])

    def model(self, garment_id: str, simplification: float | None = None) -> GarmentModel:
        """The prepared model (from memory, else disk). Another simplification degree than the entry's
        is prepared once from the kept source file and cached on disk. KeyError if unknown."""
        row = self._row(garment_id)
        if row is None:
            raise KeyError(garment_id)
        stored_b = row["simplification"]
        b = stored_b if simplification is None else float(simplification)
        if not 0.0 < b <= 1.0:
            raise ValueError(f"simplification must be in (0, 1], got {b}")
        key = garment_id if abs(b - stored_b) < 1e-9 else f"{garment_id}-B{b:.4f}"
        with self._lock:
            if key in self._cache:
                self._cache.move_to_end(key)
                cached = self._cache[key]
                words = _meta(row, cached.meta)
                if words != cached.meta:  # renamed or re-sized since (``update``, maybe by another process)
                    cached = self._cache[key] = replace(cached, meta=words)
                return cached
        directory = self.models / key
        reprepared = False
        if not GarmentModel.is_current(directory):
            reprepared = directory.exists()
            if reprepared:  # prepared by another PREPARATION_VERSION: made again from the kept source
                self._discard(directory)
            meta = GarmentMeta(**json.loads(row["meta"]))
            source = self.sources / f"{row['source_sha256']}.{row['source_ext']}"
            self._prepare_into(directory, source.read_bytes(), meta.source_name, row["requested_units"],
                               replace(meta, simplification=b), row["density"])
        model = GarmentModel.load(directory)
        if reprepared and key == garment_id:  # the listing's counts follow the model
            meta = asdict(replace(model.meta, name=row["name"], category=row["category"], size=row["size"]))
            with self._connect() as db:
                db.execute("UPDATE garments SET meta = ? WHERE id = ?", (json.dumps(meta), garment_id))
        # name, category, size, style and chart are the entry's (the uploader's words), not the model's
        model = replace(model, meta=_meta(row, model.meta))
        with self._lock:
            self._cache[key] = model
            self._cache.move_to_end(key)
            while len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        return model

    # --- writing ----------------------------------------------------------------------------------

    def ingest(self, source: Path | str | bytes, name: str | None = None, category: str = "top",
               units: str = "auto", simplify: float = DEFAULT_SIMPLIFICATION, size: str | None = None,
               filename: str | None = None, density: float = DEFAULT_DENSITY,
               max_faces: int = 400_000, style: str | None = None, chart: dict | str | None = None,
               *, same_words: bool = False) -> GarmentMeta:
        """Prepare and add a garment (a path, or bytes with ``filename``); returns the entry. The same
        file with the same parameters returns the existing entry without preparing again (with ``same_words``,
        only if the words given are the entry's: see ``plan_ingest``).
        ``category``: top | bottom | dress | auto (guessed from the file name, ``resolve_category``);
        ``units``: m | cm | mm | dm | in | auto; ``simplify``: B in (0, 1]; ``density``: kg/m^2;
        ``style``, ``size``, ``chart``: the product this is one size of, the size's label and its size-chart
        row (``sizes.check_labels``).
        GarmentError (a reason for the user) if the file or a parameter is refused."""
        return self.ingest_with_status(source, name, category, units, simplify, size, filename, density, max_faces,
                                       style, chart, same_words=same_words)[0]

    def ingest_with_status(self, source: Path | str | bytes, name: str | None = None, category: str = "top",
                           units: str = "auto", simplify: float = DEFAULT_SIMPLIFICATION,
                           size: str | None = None, filename: str | None = None,
                           density: float = DEFAULT_DENSITY, max_faces: int = 400_000,
                           style: str | None = None, chart: dict | str | None = None,
                           *, same_words: bool = False) -> tuple[GarmentMeta, bool]:
        """As ``ingest``, plus whether a new entry was made (False: it was already there). An entry that was
        already there takes the style, size and chart given (when a style is given): a catalogue made before
        styles existed gains them by ingesting its files again."""
        plan = self.plan_ingest(source, name, category, units, simplify, size, filename, density, max_faces,
                                style, chart, same_words=same_words)
        if plan.existing is not None:
            return plan.existing, False
        model = prepare_model(plan.preparation) if plan.preparation is not None else None
        return self.add_prepared(plan, model)

    def plan_ingest(self, source: Path | str | bytes, name: str | None = None, category: str = "top",
                    units: str = "auto", simplify: float = DEFAULT_SIMPLIFICATION, size: str | None = None,
                    filename: str | None = None, density: float = DEFAULT_DENSITY, max_faces: int = 400_000,
                    style: str | None = None, chart: dict | str | None = None,
                    *, same_words: bool = False) -> "IngestPlan":
        """The first third of an ingestion (``ingest``'s arguments), on the catalogue's machine: read the
        file, check the parameters, name the entry. The plan holds the existing entry when the same file
        with the same parameters is already in (taking the style, size and chart given with a style), else
        what the new entry needs: ``preparation`` for ``prepare_model`` (None when a complete model directory
        is already in place, e.g. left by a crash: it is adopted) and the row's fields for ``add_prepared``.
        GarmentError if the file or a parameter is refused; with ``same_words`` (an upload) also, 409, when
        the file is already in under another name, or with another size or chart given without a style
        (the entry would be taken as it is and those words dropped): ``update`` changes an entry's words."""
        if isinstance(source, (bytes, bytearray)):
            data = bytes(source)
            if filename is None:
                raise GarmentError("a file name is needed to know the file type")
        else:
            path = Path(source)
            data = path.read_bytes()
            filename = filename or path.name
        ext = file_extension(filename)
        asked_category = category
        category = resolve_category(category, filename)
        style, size, chart = check_labels(style, size, chart)
        if not 0.0 < simplify <= 1.0:
            raise GarmentError(f"simplify must be in (0, 1], got {simplify}")
        if not density > 0.0:
            raise GarmentError(f"density must be positive (kg/m^2), got {density}")
        given_name = (name or "").strip() or None
        name = given_name or Path(filename).stem
        sha = hashlib.sha256(data).hexdigest()
        gid = entry_id(sha, units, simplify, density)
        plan = IngestPlan(gid=gid, name=name, category=category, size=size, units=units, simplify=float(simplify),
                          density=float(density), sha256=sha, ext=ext, style=style, chart=chart, data=data)
        existing = self.get(gid)
        if existing is not None:
            check_readable(data, filename)  # the same bytes under another name must still be what it says
            if asked_category != "auto" and category != existing.category:
                # the entry's id does not hold the category (ids stay what they were): the same file asked for
                # as another kind of garment is a conflict to resolve, not the old entry to take silently
                raise GarmentError(f"this file is already in the catalogue as a {existing.category} (garment "
                                   f"{gid}, {existing.name!r}): delete it first to add it as a {category}",
                                   status=409, field="category")
            if same_words:
                _refuse_other_words(existing, given_name, size, chart, style)
            if style is not None and (existing.style, existing.size, existing.chart) != (style, size, chart):
                self._check_size_free(style, size, gid)
                with self._connect() as db:
                    db.execute("UPDATE garments SET style = ?, size = ?, chart = ? WHERE id = ?",
                               (style, size, json.dumps(chart) if chart else None, gid))
                return replace(plan, existing=self.get(gid))
            return replace(plan, existing=existing)
        if style is not None:
            self._check_size_free(style, size, gid)
        directory = self.models / gid
        if GarmentModel.is_current(directory):
            return plan
        if directory.exists():  # a leftover of another preparation version: not adopted
            self._discard(directory)
        meta = GarmentMeta(
            id=gid, name=name, category=category, size=size, units=units, units_guessed=False,
            simplification=float(simplify), source_sha256=sha, source_name=filename, vertices=0,
            faces=0, coarse_vertices=0, coarse_faces=0,
        )
        return replace(plan, preparation=Preparation(data, filename, units, meta, float(density), int(max_faces)))

    def add_prepared(self, plan: "IngestPlan", model: GarmentModel | None) -> tuple[GarmentMeta, bool]:
        """The last third of an ingestion: put ``model`` (``prepare_model`` of ``plan.preparation``, made here
        or on another machine; None if the plan needs none) into place atomically, keep the source, insert
        the row. Returns (the entry, whether this call made it: False if another ingestion of the same file
        won the race)."""
        directory = self.models / plan.gid
        if model is not None:
            self._save_into(directory, model)
        self._store_source(plan.sha256, plan.ext, plan.data)  # kept so that other simplification degrees can be made
        meta = json.loads((directory / "meta.json").read_text())
        # name/category/size are the uploader's words for this entry, not part of the prepared model
        meta.update(name=plan.name, category=plan.category, size=plan.size)
        created = self._insert_row(plan.gid, plan.name, plan.category, plan.size, meta, plan.units, plan.simplify,
                                   plan.density, plan.sha256, plan.ext, plan.style, plan.chart)
        return self.get(plan.gid), created

    def update(self, garment_id: str, **words) -> GarmentMeta | None:
        """Change an entry's own words: any of ``name``, ``size``, ``style``, ``chart`` (a size-chart row, a dict
        or its JSON text); a ``size``, ``style`` or ``chart`` of None removes it. Checked as an upload's are
        (``sizes.check_labels`` on the entry's words as they would be, a style's size free); the prepared
        model is the file's and stays as it is. Returns the changed entry, None if there is no such id;
        GarmentError (nothing changed) if a word is refused. Cached models take the new words on their next
        ``model`` call, in every process sharing the catalogue."""
        unknown = sorted(set(words) - set(WORDS))
        if unknown:
            raise GarmentError(f"{unknown[0]} cannot be changed: an entry's {', '.join(WORDS)} can", field=unknown[0])
        current = self.get(garment_id)
        if current is None:
            return None
        name = current.name
        if "name" in words:
            name = (words["name"] or "").strip()
            if not name:
                raise GarmentError("must not be blank", field="name")
            if len(name) > NAME_MAX_CHARS:
                raise GarmentError(f"must be at most {NAME_MAX_CHARS} characters, got {len(name):,}", field="name")
        merged = {"style": current.style, "size": current.size, "chart": current.chart,
                  **{k: words[k] for k in ("style", "size", "chart") if k in words}}
        for field, check in (("style", check_style), ("size", check_size), ("chart", parse_chart)):
            try:
                merged[field] = check(merged[field])
            except GarmentError as exc:
                raise GarmentError(str(exc), exc.status, field=field) from None
        try:  # a style or a chart row without a size: the size is missing
            style, size, chart = check_labels(merged["style"], merged["size"], merged["chart"])
        except GarmentError as exc:
            raise GarmentError(str(exc), exc.status, field="size") from None
        if style is not None:
            self._check_size_free(style, size, garment_id)
        with self._connect() as db:
            db.execute("BEGIN IMMEDIATE")
            done = db.execute("UPDATE garments SET name = ?, size = ?, style = ?, chart = ? WHERE id = ?",
                              (name, size, style, json.dumps(chart) if chart else None, garment_id)).rowcount
        return self.get(garment_id) if done else None

    def delete(self, garment_id: str) -> bool:
        """Remove an entry, its prepared models and (if no other entry uses it) its source file.
        False if there was no such id."""
        with self._connect() as db:
            db.execute("BEGIN IMMEDIATE")
            row = db.execute("SELECT source_sha256, source_ext FROM garments WHERE id = ?", (garment_id,)).fetchone()
            if row is None:
                return False
            db.execute("DELETE FROM garments WHERE id = ?", (garment_id,))
            others = db.execute("SELECT COUNT(*) FROM garments WHERE source_sha256 = ?", (row[0],)).fetchone()[0]
        with self._lock:
            for key in [k for k in self._cache if k.split("-B")[0] == garment_id]:
                del self._cache[key]
        for d in list(self.models.glob(f"{garment_id}*")):
            if d.name == garment_id or d.name.startswith(f"{garment_id}-B"):
                self._discard(d)
        if others == 0:
            (self.sources / f"{row[0]}.{row[1]}").unlink(missing_ok=True)
        return True

    # --- internals --------------------------------------------------------------------------------

    def _connect(self) -> sqlite3.Connection:
        db = sqlite3.connect(self.db_path, timeout=SQLITE_TIMEOUT_S, isolation_level=None)
        db.row_factory = sqlite3.Row
        return _Closing(db)

    def _insert_row(self, gid, name, category, size, meta, units, simplify, density, sha, ext, style=None,
                    chart=None) -> bool:
        """Add the index row in one transaction; False if another ingestion added it first."""
        with self._connect() as db:
            db.execute("BEGIN IMMEDIATE")
            cur = db.execute(
                "INSERT OR IGNORE INTO garments (id, name, category, size, style, chart, units, requested_units, "
                "simplification, density, source_sha256, source_ext, meta, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (gid, name, category, size, style, json.dumps(chart) if chart else None, meta["units"], units,
                 float(simplify), float(density), sha, ext, json.dumps(meta), time.time()),
            )
            return cur.rowcount == 1

    def _check_size_free(self, style: str, size: str, gid: str) -> None:
        """GarmentError (409) if another entry already is this style's ``size``."""
        for other in self.style(style):
            if other.id != gid and (other.size or "").upper() == size.upper():
                raise GarmentError(f"style {style!r} already has a size {other.size} (garment {other.id}, "
                                   f"{other.name!r}): delete it first, or give another size label", status=409,
                                   field="style")

    def _row(self, garment_id: str):
        with self._connect() as db:
            return db.execute("SELECT * FROM garments WHERE id = ?", (garment_id,)).fetchone()

    def _work_dir(self) -> Path:
        d = self.tmp / f"{os.getpid()}-{uuid.uuid4().hex}"
        d.mkdir()
        return d

    def _store_source(self, sha: str, ext: str, data: bytes) -> None:
        target = self.sources / f"{sha}.{ext}"
        if target.exists():
            return
        work = self._work_dir()
        try:
            (work / "source").write_bytes(data)
            os.replace(work / "source", target)
        finally:
            shutil.rmtree(work, ignore_errors=True)

    def _prepare_into(self, directory: Path, data: bytes, filename: str, units: str, meta: GarmentMeta,
                      density: float, max_faces: int = 400_000) -> None:
        """Prepare a model and move it to ``directory`` atomically (first one wins)."""
        self._save_into(directory, prepare_model(Preparation(data, filename, units, meta, density, max_faces)))

    def _save_into(self, directory: Path, model: GarmentModel) -> None:
        """Save ``model`` into a work dir and move it to ``directory`` atomically (first one wins)."""
        work = self._work_dir()
        try:
            model.save(work)
            try:
                os.replace(work, directory)
            except OSError:
                if not (directory / "meta.json").exists():  # not a lost race: a real failure
                    raise
        finally:
            shutil.rmtree(work, ignore_errors=True)

    def _discard(self, directory: Path) -> None:
        """Move a directory out of the way atomically, then delete it."""
        trash = self.tmp / f"del-{uuid.uuid4().hex}"
        try:
            os.replace(directory, trash)
        except OSError:
            return
        shutil.rmtree(trash, ignore_errors=True)

    def _remove_stale_tmp(self) -> None:
        now = time.time()
        for d in self.tmp.iterdir():
            try:
                if now - d.stat().st_mtime > STALE_TMP_S:
                    shutil.rmtree(d, ignore_errors=True) if d.is_dir() else d.unlink()
            except OSError:
                pass


class _Closing:
    """sqlite3 connection as a context manager that commits/rolls back and always closes."""

    def __init__(self, db: sqlite3.Connection):
        self.db = db

    def __enter__(self) -> sqlite3.Connection:
        return self.db

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if self.db.in_transaction:
                self.db.execute("ROLLBACK" if exc_type else "COMMIT")
        finally:
            self.db.close()


def _meta(row, base: GarmentMeta | None = None) -> GarmentMeta:
    """An index row's GarmentMeta: the stored meta (or ``base``, a prepared model's) with the entry's own
    words from the row's columns (name, category, size, style, chart)."""
    meta = base if base is not None else GarmentMeta(**json.loads(row["meta"]))
    return replace(meta, id=row["id"], name=row["name"], category=row["category"], size=row["size"],
                   style=row["style"], chart=json.loads(row["chart"]) if row["chart"] else None)


def _refuse_other_words(existing: GarmentMeta, name: str | None, size: str | None, chart: dict | None,
                        style: str | None) -> None:
    """GarmentError (409) for an upload of a file already in as ``existing`` with words it would drop: another
    ``name``, or (without a ``style``, with which the entry takes them) another ``size`` or ``chart``."""
    other = []  # (field, how it differs)
    if name is not None and name != existing.name:
        other.append(("name", f"its name is {existing.name!r}, not {name!r}"))
    if style is None and size is not None and size != existing.size:
        other.append(("size", f"its size is {existing.size or 'none'}, not {size}"))
    if style is None and chart is not None and chart != existing.chart:
        other.append(("size_chart", f"its size chart is {json.dumps(existing.chart) if existing.chart else 'none'}, "
                                    f"not {json.dumps(chart)}"))
    if other:
        raise GarmentError(f"this file is already in the catalogue as garment {existing.id} "
                           f"({'; '.join(text for _, text in other)}): to change its words, PATCH "
                           f"/api/garments/{existing.id} with them (name, size, style, chart); a file is kept once",
                           status=409, field=other[0][0])


def meta_dict(meta: GarmentMeta) -> dict:
    """The entry as a plain dict (for JSON)."""
    return asdict(meta)
