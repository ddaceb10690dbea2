"""The garment catalogue: an SQLite index plus a directory of prepared arrays per garment.

Layout under ``data_dir``::

    catalogue.sqlite            index: one row per catalogue entry (GarmentMeta + preparation params)
    sources/<sha256>.<ext>      the uploaded file, kept so that other simplification degrees can be made
    models/<key>/               model.npz + meta.json + prepared.json (GarmentModel.save); key = id for the
                                entry itself, id-B<b> for a variant with another simplification degree;
                                a model of another PREPARATION_VERSION is prepared again from its source
    tmp/                        work directories; anything here is a leftover of a crash

An entry's id is a short hash of the file's sha256 and the preprocessing parameters (units,
simplification, a density given), so the same file with the same parameters is the same entry (idempotent).
Its fabric (``fabric.FABRICS``; by default its category's) is one of the entry's words, which ``update`` changes;
its masses are made of the fabric's density unless the ingestion gave one, and follow the fabric when it
changes (``update``; ``model`` rescales a stored model whose masses are of another density than its row's).
Writes are atomic: the model is prepared in ``tmp/``, moved into place with ``os.replace`` (atomic on one
file system), and only then is the row inserted in a transaction. A crash leaves no row, and at worst a
complete model directory without a row, which the next ingestion of that file adopts. Two ingestions at
once (threads or processes) race only on the rename and the ``INSERT OR IGNORE``; both end with the same
single entry.
"""

from __future__ import annotations

import hashlib
import json
import math
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

from tryon.garment.fabric import DEFAULT_FABRIC, FABRICS, Fabric, fabric_named
from tryon.garment.ingest import GarmentError, check_readable, file_extension, load_garment
from tryon.garment.model import GarmentMeta, GarmentModel
from tryon.garment.prepare import DEFAULT_SIMPLIFICATION, prepare, triangle_areas
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
WORDS = ("name", "size", "style", "chart", "fabric")
# Every entry's density before fabrics, kg/m^2 (the one default then). An id whose density is the fabric's own is
# keyed with it, so that the entries made then keep their ids; a catalogue from then takes each entry's category's
# fabric and its density when it is opened (``Catalogue._add_columns``).
LEGACY_DENSITY = 0.15
# Relative difference past which a model's masses are of another density than its entry's (float sums agree to
# ~1e-15).
DENSITY_TOLERANCE = 1e-6
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
_ADDED_COLUMNS = (("style", "TEXT"), ("chart", "TEXT"), ("fabric", "TEXT"))


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


def entry_id(sha256: str, units: str, simplification: float, density: float | None) -> str:
    """12 hex digits naming (file content, preprocessing parameters). ``density`` None: the fabric's own (the
    fabric is a word of the entry, not part of its id), keyed as ``LEGACY_DENSITY`` was, so that ids made before
    fabrics stay; a density given is keyed by its value (0.15 given apart from the fabric's)."""
    if density is None:
        keyed = f"{LEGACY_DENSITY:.5f}"
    else:
        keyed = f"{density:.5f}" + (" given" if f"{density:.5f}" == f"{LEGACY_DENSITY:.5f}" else "")
    key = f"{sha256}|units={units}|B={simplification:.4f}|density={keyed}"
    return hashlib.sha256(key.encode()).hexdigest()[:12]


def check_fabric(name: str | None, category: str) -> Fabric:
    """The fabric ``name`` (``fabric.FABRICS``), the category's (``fabric.DEFAULT_FABRIC``) for None or a blank.
    GarmentError (422, field fabric) naming the fabrics for another name."""
    name = (name or "").strip() or None
    try:
        return fabric_named(name, category)
    except ValueError:
        raise GarmentError(f"unknown fabric {name[:40]!r}: choose one of {', '.join(FABRICS)} (GET /api/fabrics "
                           "gives their weight and stiffness)", field="fabric") from None


@dataclass(frozen=True)
class Preparation:
    """What preparing one new entry needs, as plain data (it may travel to another process or machine, see
    ``tryon ingest --ray``): the file's bytes and name, its units, the entry's meta so far (with its fabric), the
    masses' density (kg/m^2: the fabric's, or the one given) and the largest mesh taken (faces)."""

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
                   source_name=m.source_name, simplification=m.simplification, density=job.density,
                   fabric=m.fabric)


@dataclass(frozen=True)
class IngestPlan:
    """One ingestion between ``Catalogue.plan_ingest`` and ``Catalogue.add_prepared``: the entry's id and
    row fields, the file's bytes, and either the existing entry or the preparation a new one needs. ``density``:
    the masses' (kg/m^2: the fabric's unless one was given); ``fabric``: its name."""

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
    fabric: str = "jersey"
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
            self._add_columns(db)
        self._remove_stale_tmp()

    @staticmethod
    def _add_columns(db: sqlite3.Connection) -> None:
        """Give an index made before some columns existed those columns (``_ADDED_COLUMNS``), in one transaction
        (another process opening it at once waits, then finds them). One made before fabrics: each entry takes its
        category's fabric, and an entry of the one density then (``LEGACY_DENSITY``) the fabric's density (its
        model is prepared again: ``PREPARATION_VERSION``)."""
        if {c for c, _ in _ADDED_COLUMNS} <= {r[1] for r in db.execute("PRAGMA table_info(garments)")}:
            return  # nothing to add: no write lock taken
        db.execute("BEGIN IMMEDIATE")
        have = {r[1] for r in db.execute("PRAGMA table_info(garments)")}
        for column, kind in _ADDED_COLUMNS:
            if column not in have:
                db.execute(f"ALTER TABLE garments ADD COLUMN {column} {kind}")
        if "fabric" not in have:
            for category, name in DEFAULT_FABRIC.items():
                db.execute("UPDATE garments SET fabric = ? WHERE category = ?", (name, category))
                db.execute("UPDATE garments SET density = ? WHERE category = ? AND abs(density - ?) < 1e-9",
                           (FABRICS[name].density, category, LEGACY_DENSITY))

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
                if words != cached.meta:  # changed since (``update``, maybe by another process): its words, and
                    # its masses if its fabric's density came with them
                    cached = self._cache[key] = _of_density(replace(cached, meta=words), cached.meta.density)
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
                               replace(meta, simplification=b, fabric=row["fabric"]), row["density"])
        model = GarmentModel.load(directory)
        made = mass_density(model)
        if reprepared and key == garment_id:  # the listing's counts follow the model
            meta = asdict(replace(model.meta, name=row["name"], category=row["category"], size=row["size"]))
            with self._connect() as db:
                db.execute("UPDATE garments SET meta = ? WHERE id = ?", (json.dumps(meta), garment_id))
        # name, category, size, style, chart and fabric are the entry's (the uploader's words), not the model's; its
        # masses are of the entry's density (a fabric changed by another process while this one read the files)
        model = _of_density(replace(model, meta=_meta(row, model.meta)), made)
        with self._lock:
            self._cache[key] = model
            self._cache.move_to_end(key)
            while len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        return model

    # --- writing ----------------------------------------------------------------------------------

    def ingest(self, source: Path | str | bytes, name: str | None = None, category: str = "top",
               units: str = "auto", simplify: float = DEFAULT_SIMPLIFICATION, size: str | None = None,
               filename: str | None = None, density: float | None = None,
               max_faces: int = 400_000, style: str | None = None, chart: dict | str | None = None,
               fabric: str | None = None, *, same_words: bool = False) -> GarmentMeta:
        """Prepare and add a garment (a path, or bytes with ``filename``); returns the entry. The same
        file with the same parameters returns the existing entry without preparing again (with ``same_words``,
        only if the words given are the entry's: see ``plan_ingest``).
        ``category``: top | bottom | dress | auto (guessed from the file name, ``resolve_category``);
        ``units``: m | cm | mm | dm | in | auto; ``simplify``: B in (0, 1]; ``fabric``: a name in
        ``fabric.FABRICS`` (None: the category's, ``fabric.DEFAULT_FABRIC``); ``density``: kg/m^2 of the masses
        (None: the fabric's); ``style``, ``size``, ``chart``: the product this is one size of, the size's label and
        its size-chart row (``sizes.check_labels``).
        GarmentError (a reason for the user) if the file or a parameter is refused."""
        return self.ingest_with_status(source, name, category, units, simplify, size, filename, density, max_faces,
                                       style, chart, fabric, same_words=same_words)[0]

    def ingest_with_status(self, source: Path | str | bytes, name: str | None = None, category: str = "top",
                           units: str = "auto", simplify: float = DEFAULT_SIMPLIFICATION,
                           size: str | None = None, filename: str | None = None,
                           density: float | None = None, max_faces: int = 400_000,
                           style: str | None = None, chart: dict | str | None = None, fabric: str | None = None,
                           *, same_words: bool = False) -> tuple[GarmentMeta, bool]:
        """As ``ingest``, plus whether a new entry was made (False: it was already there). An entry that was
        already there with no style takes the style, size and chart given (when a style is given): a catalogue
        made before styles existed gains them by ingesting its files again. One with a style keeps its own words
        (changed since with ``update``: ``scripts/serve.sh`` ingests garments/ at every start)."""
        plan = self.plan_ingest(source, name, category, units, simplify, size, filename, density, max_faces,
                                style, chart, fabric, same_words=same_words)
        if plan.existing is not None:
            return plan.existing, False
        model = prepare_model(plan.preparation) if plan.preparation is not None else None
        return self.add_prepared(plan, model)

    def plan_ingest(self, source: Path | str | bytes, name: str | None = None, category: str = "top",
                    units: str = "auto", simplify: float = DEFAULT_SIMPLIFICATION, size: str | None = None,
                    filename: str | None = None, density: float | None = None, max_faces: int = 400_000,
                    style: str | None = None, chart: dict | str | None = None, fabric: str | None = None,
                    *, same_words: bool = False) -> "IngestPlan":
        """The first third of an ingestion (``ingest``'s arguments), on the catalogue's machine: read the
        file, check the parameters, name the entry. The plan holds the existing entry when the same file
        with the same parameters is already in (one with no style taking the style, size and chart given with a
        style; its fabric stays its own), else
        what the new entry needs: ``preparation`` for ``prepare_model`` (None when a complete model directory
        is already in place, e.g. left by a crash: it is adopted) and the row's fields for ``add_prepared``.
        GarmentError if the file or a parameter is refused; with ``same_words`` (an upload) also, 409, when
        the file is already in under another name, fabric, style, size or chart (the entry would be taken as it
        is and those words dropped; an entry with no style takes a style given, with its size and chart):
        ``update`` changes an entry's words."""
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
        given_fabric = (fabric or "").strip() or None
        material = check_fabric(given_fabric, category)
        if not 0.0 < simplify <= 1.0:
            raise GarmentError(f"simplify must be in (0, 1], got {simplify}")
        if density is not None and not (math.isfinite(density) and density > 0.0):
            raise GarmentError(f"density must be a positive number (kg/m^2), got {density}", field="density")
        given_name = (name or "").strip() or None
        name = given_name or Path(filename).stem
        sha = hashlib.sha256(data).hexdigest()
        gid = entry_id(sha, units, simplify, density)
        mass_density_ = material.density if density is None else float(density)
        plan = IngestPlan(gid=gid, name=name, category=category, size=size, units=units, simplify=float(simplify),
                          density=mass_density_, sha256=sha, ext=ext, style=style, chart=chart, data=data,
                          fabric=material.name)
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
                _refuse_other_words(existing, given_name, size, chart, style, given_fabric)
            if style is not None and existing.style is None:  # a catalogue made before styles gains them; an
                # entry with a style keeps its own (PATCHed ones too: serve.sh ingests garments/ at every start)
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
            faces=0, coarse_vertices=0, coarse_faces=0, fabric=material.name, density=mass_density_,
        )
        return replace(plan, preparation=Preparation(data, filename, units, meta, mass_density_, int(max_faces)))

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
        # name/category/size/fabric are the uploader's words for this entry, not part of the prepared model
        meta.update(name=plan.name, category=plan.category, size=plan.size, fabric=plan.fabric, density=plan.density)
        created = self._insert_row(plan.gid, plan.name, plan.category, plan.size, meta, plan.units, plan.simplify,
                                   plan.density, plan.sha256, plan.ext, plan.style, plan.chart, plan.fabric)
        return self.get(plan.gid), created

    def update(self, garment_id: str, **words) -> GarmentMeta | None:
        """Change an entry's own words: any of ``name``, ``size``, ``style``, ``chart`` (a size-chart row, a dict
        or its JSON text), ``fabric`` (a name in ``fabric.FABRICS``; None: the category's); a ``size``, ``style``
        or ``chart`` of None removes it. Checked as an upload's are (``sizes.check_labels`` on the entry's words
        as they would be, a style's size free, ``check_fabric``); the prepared model is the file's and stays as it
        is, but for its masses: an entry whose density was its old fabric's takes the new fabric's, and its stored
        models (``models/<id>`` and other simplification degrees') are rescaled by the ratio and saved again (an
        entry given its own density at ingestion keeps it). The id stays. Returns the changed entry, None if there
        is no such id; GarmentError (nothing changed) if a word is refused. Cached models take the new words (and
        masses) on their next ``model`` call, in every process sharing the catalogue."""
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
        fabric = check_fabric(words["fabric"], current.category) if "fabric" in words else None
        with self._connect() as db:
            db.execute("BEGIN IMMEDIATE")
            row = db.execute("SELECT category, fabric, density FROM garments WHERE id = ?", (garment_id,)).fetchone()
            if row is None:  # deleted meanwhile
                return None
            old = check_fabric(row["fabric"], row["category"])
            new = fabric or old
            density = row["density"]
            if new.name != old.name and abs(density - old.density) <= DENSITY_TOLERANCE * old.density:
                density = new.density  # the masses were the old fabric's: they become the new one's
            db.execute("UPDATE garments SET name = ?, size = ?, style = ?, chart = ?, fabric = ?, density = ? "
                       "WHERE id = ?", (name, size, style, json.dumps(chart) if chart else None, new.name, density,
                                        garment_id))
        if density != row["density"]:
            self._rescale_models(garment_id)
        return self.get(garment_id)

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

    def _rescale_models(self, garment_id: str) -> None:
        """The stored models of an entry (its own and other simplification degrees') saved again with its row's
        fabric and density, their masses rescaled to that density (``_of_density``). Each file is replaced
        atomically (``os.replace``, masses first); a reader meanwhile gets the old or the new file of each, and
        ``model`` rescales masses of another density than the row's, so a crash between them loses nothing."""
        row = self._row(garment_id)
        if row is None:
            return
        for directory in self.models.glob(f"{garment_id}*"):
            if not (directory.name == garment_id or directory.name.startswith(f"{garment_id}-B")):
                continue
            if not GarmentModel.is_current(directory):
                continue  # prepared again from its source, with the row's density, when it is next asked for
            work = self._work_dir()
            try:
                model = GarmentModel.load(directory)
                model = _of_density(replace(model, meta=replace(model.meta, fabric=row["fabric"],
                                                                density=row["density"])), mass_density(model))
                model.save(work)
                for name in ("model.npz", "meta.json"):
                    os.replace(work / name, directory / name)
            except FileNotFoundError:  # deleted meanwhile
                pass
            finally:
                shutil.rmtree(work, ignore_errors=True)

    def _connect(self) -> sqlite3.Connection:
        db = sqlite3.connect(self.db_path, timeout=SQLITE_TIMEOUT_S, isolation_level=None)
        db.row_factory = sqlite3.Row
        return _Closing(db)

    def _insert_row(self, gid, name, category, size, meta, units, simplify, density, sha, ext, style=None,
                    chart=None, fabric=None) -> bool:
        """Add the index row in one transaction; False if another ingestion added it first."""
        with self._connect() as db:
            db.execute("BEGIN IMMEDIATE")
            cur = db.execute(
                "INSERT OR IGNORE INTO garments (id, name, category, size, style, chart, fabric, units, "
                "requested_units, simplification, density, source_sha256, source_ext, meta, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (gid, name, category, size, style, json.dumps(chart) if chart else None, fabric, meta["units"],
                 units, float(simplify), float(density), sha, ext, json.dumps(meta), time.time()),
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
                   style=row["style"], chart=json.loads(row["chart"]) if row["chart"] else None,
                   fabric=row["fabric"], density=row["density"])


def mass_density(model: GarmentModel) -> float | None:
    """kg/m^2 a model's masses are made of: their sum over the full mesh's area (``prepare.lumped_masses`` makes
    it so); None for a mesh of no area."""
    area = float(triangle_areas(model.vertices, model.faces).sum())
    return float(model.mass.sum()) / area if area > 0.0 else None


def _of_density(model: GarmentModel, made: float | None) -> GarmentModel:
    """``model`` with masses of its meta's density (kg/m^2), from masses of ``made`` kg/m^2: scaled by the
    ratio, the same if they agree (``DENSITY_TOLERANCE``) or either is unknown."""
    want = model.meta.density
    if want is None or made is None or abs(want - made) <= DENSITY_TOLERANCE * want:
        return model
    return replace(model, mass=model.mass * (want / made))


def _refuse_other_words(existing: GarmentMeta, name: str | None, size: str | None, chart: dict | None,
                        style: str | None, fabric: str | None = None) -> None:
    """GarmentError (409) for an upload of a file already in as ``existing`` with words it would drop: another
    ``name`` or ``fabric``, or another ``style``, ``size`` or ``chart`` (unless the entry has no style and one is
    given: it then takes them)."""
    other = []  # (field, how it differs)
    takes_labels = style is not None and existing.style is None
    if name is not None and name != existing.name:
        other.append(("name", f"its name is {existing.name!r}, not {name!r}"))
    had = check_fabric(existing.fabric, existing.category).name
    if fabric is not None and fabric != had:
        other.append(("fabric", f"its fabric is {had}, not {fabric}"))
    if not takes_labels and style is not None and style != existing.style:
        other.append(("style", f"its style is {existing.style}, not {style}"))
    if not takes_labels and size is not None and size != existing.size:
        other.append(("size", f"its size is {existing.size or 'none'}, not {size}"))
    if not takes_labels and chart is not None and chart != existing.chart:
        other.append(("size_chart", f"its size chart is {json.dumps(existing.chart) if existing.chart else 'none'}, "
                                    f"not {json.dumps(chart)}"))
    if other:
        raise GarmentError(f"this file is already in the catalogue as garment {existing.id} "
                           f"({'; '.join(text for _, text in other)}): to change its words, PATCH "
                           f"/api/garments/{existing.id} with them ({', '.join(WORDS)}); a file is kept once",
                           status=409, field=other[0][0])


def meta_dict(meta: GarmentMeta) -> dict:
    """The entry as a plain dict (for JSON)."""
    return asdict(meta)
