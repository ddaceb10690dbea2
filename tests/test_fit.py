"""Issue 27, which size fits me: styles and size charts in the catalogue (SQLite, upload form, ``tryon ingest``),
``GET /api/styles``, the ease measured on a known garment, ``POST /api/fit`` (a person at a chart row's centre
gets that size, two sizes smaller is tight, its drapes answer a later ``/api/tryon`` from the cache, a full
pool is a 503, an unknown style 404, bad measurements 422) and ``tryon fit``.

The catalogue is generated here (``tryon.garment.generate``): the T-shirt and the trousers in their five sizes
with the chart rows the generator built them from, shared by the module.
"""

from __future__ import annotations

import json
import sqlite3
import threading
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tryon.api.app import create_app
from tryon.api.pool import get_pool
from tryon.body.build import build_body
from tryon.body.params import Measurements
from tryon.cli import main
from tryon.config import Settings
from tryon.fit.advice import advise_size
from tryon.fit.ease import measure_ease
from tryon.fit.verdict import length_notes
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import GARMENTS, SIZE_CHART, chart_row, garment_mesh, half_axes, obj_text, spow
from tryon.garment.ingest import GarmentError
from tryon.garment.sizes import parse_chart, size_order
from tryon.sim.run import drape
from tryon.sim.settings import SimSettings

ROOT = Path(__file__).resolve().parents[1]
AUTH = {"Authorization": "Bearer t"}
SIZES = list(SIZE_CHART)  # S, M, L, XL, XXL
# People at the centre of the chart's M and L rows (cm).
AT_M = {"height": 170, "chest": 96, "waist": 82, "hips": 100}
AT_L = {"height": 178, "chest": 104, "waist": 90, "hips": 106}


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[tuple[str, str], Path]:
    """OBJ files of the T-shirt and the trousers in every size."""
    root = tmp_path_factory.mktemp("fit-src")
    out = {}
    for kind in ("tshirt", "trousers"):
        for size in SIZES:
            out[kind, size] = root / f"{kind}-{size.lower()}.obj"
            out[kind, size].write_text(obj_text(garment_mesh(kind, size), f"{kind} {size}"))
    return out


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory, files) -> Path:
    """A catalogue of the two styles, each size ingested with its chart row, in a shuffled order (the style
    keeps its sizes' order, not the ingestion's)."""
    data = tmp_path_factory.mktemp("fit-data")
    catalogue = Catalogue(data)
    for kind in ("tshirt", "trousers"):
        name, category = GARMENTS[kind]
        for size in ("L", "S", "XXL", "M", "XL"):
            catalogue.ingest(files[kind, size], name=f"{name} {size}", category=category, units="m", size=size,
                             style=kind, chart=chart_row(size, category))
    return data


@pytest.fixture(scope="module")
def client(data_dir):
    with TestClient(create_app(Settings(data_dir=data_dir, admin_token="t"))) as c:
        yield c


# --- styles and charts in the catalogue -------------------------------------------------------------------


def test_styles_keep_their_sizes_in_order_with_their_charts(data_dir):
    styles = Catalogue(data_dir).styles()
    assert list(styles) == ["tshirt", "trousers"]
    for kind, category in (("tshirt", "top"), ("trousers", "bottom")):
        entries = styles[kind]
        assert [e.size for e in entries] == SIZES
        assert all(e.style == kind and e.category == category for e in entries)
        assert [e.chart for e in entries] == [chart_row(s, category) for s in SIZES]
    assert styles["tshirt"][1].chart == {"chest": [92.0, 100.0], "waist": [78.0, 86.0]}


def test_size_order_letters_numbers_and_as_given():
    assert [["XL", "s", "M", "2XL"][i] for i in size_order(["XL", "s", "M", "2XL"])] == ["s", "M", "XL", "2XL"]
    assert [["40", "36", "38"][i] for i in size_order(["40", "36", "38"])] == ["36", "38", "40"]
    assert size_order(["petite", "regular", "tall"]) == [0, 1, 2]


def test_the_catalogue_file_gives_six_styles_of_five_sizes_with_the_generators_charts():
    entries = json.loads((ROOT / "garments" / "catalogue.json").read_text())
    styles = {}
    for e in entries:
        styles.setdefault(e["style"], []).append(e)
        assert e["chart"] == chart_row(e["size"], e["category"]), e["file"]
        assert parse_chart(e["chart"]) == e["chart"]
    assert list(styles) == list(GARMENTS)
    assert all([e["size"] for e in v] == SIZES for v in styles.values())


def test_a_catalogue_made_before_styles_gains_them_by_ingesting_again(tmp_path, files):
    catalogue = Catalogue(tmp_path)
    first = catalogue.ingest(files["tshirt", "M"], category="top", units="m", size="M")
    with sqlite3.connect(tmp_path / "catalogue.sqlite") as db:  # the schema before issue 27
        db.execute("ALTER TABLE garments DROP COLUMN style")
        db.execute("ALTER TABLE garments DROP COLUMN chart")
    reopened = Catalogue(tmp_path)
    assert [(e.id, e.style, e.chart) for e in reopened.list()] == [(first.id, None, None)]
    assert reopened.styles() == {}
    again, created = reopened.ingest_with_status(files["tshirt", "M"], category="top", units="m", size="M",
                                                 style="tshirt", chart='{"chest": [92, 100]}')
    assert not created and again.id == first.id
    assert (again.style, again.size, again.chart) == ("tshirt", "M", {"chest": [92.0, 100.0]})
    assert reopened.model(first.id).meta.style == "tshirt"


@pytest.mark.parametrize("chart, words", [
    ('{"chest": [92, 100', "size chart is not valid JSON"),
    ('[92, 100]', "size chart must be a JSON object"),
    ('{"bust": 90}', "unknown key 'bust'"),
    ('{"chest": [100, 92]}', "chest min 100 cm is greater than its max 92 cm"),
    ('{"hips": [20, 30]}', "outside the plausible range [75, 150] cm"),
    ('{"waist": "80"}', "waist must be a number or [min, max]"),
    ('{"waist": [70, 80, 90]}', "waist must be a number or [min, max]"),
])
def test_size_chart_refusals(chart, words):
    with pytest.raises(GarmentError, match=words.replace("[", r"\[").replace("]", r"\]")):
        parse_chart(chart)


def test_a_style_needs_a_size_and_a_short_id(tmp_path, files):
    catalogue = Catalogue(tmp_path)
    with pytest.raises(GarmentError, match="needs a size label"):
        catalogue.ingest(files["tshirt", "S"], category="top", units="m", style="tshirt")
    with pytest.raises(GarmentError, match="short id"):
        catalogue.ingest(files["tshirt", "S"], category="top", units="m", size="S", style="T shirt")
    catalogue.ingest(files["tshirt", "S"], category="top", units="m", size="S", style="tshirt")
    with pytest.raises(GarmentError, match="already has a size S") as refused:
        catalogue.ingest(files["tshirt", "M"], category="top", units="m", size="s", style="tshirt")
    assert refused.value.status == 409
    assert len(catalogue.list()) == 1


# --- the API: upload form, styles, garments ---------------------------------------------------------------


def test_get_styles_and_garments_show_style_and_size(client):
    styles = client.get("/api/styles").json()
    assert [(s["style"], s["name"], s["category"]) for s in styles] == [("tshirt", "T-shirt", "top"),
                                                                      ("trousers", "Trousers", "bottom")]
    garments = {g["id"]: g for g in client.get("/api/garments").json()["garments"]}
    for style in styles:
        assert [s["size"] for s in style["sizes"]] == SIZES
        for s in style["sizes"]:
            g = garments[s["garment_id"]]
            assert (g["style"], g["size"], g["chart"]) == (style["style"], s["size"], s["chart"])
            assert s["chart"] == chart_row(s["size"], style["category"])


def test_upload_form_takes_style_size_and_chart(tmp_path, files):
    data = files["tshirt", "S"].read_bytes()
    with TestClient(create_app(Settings(data_dir=tmp_path, admin_token="t"))) as c:
        def upload(**form):
            fields = {"name": "Tee S", "category": "top", "units": "m", **form}
            return c.post("/api/garments", files={"file": ("tee.obj", data)}, data=fields, headers=AUTH)

        for form, status, words in (
                (dict(style="tee", size="S", size_chart='{"chest": [84, 92'), 422, "size chart is not valid JSON"),
                (dict(style="tee", size="S", size_chart='{"neck": 38}'), 422, "unknown key 'neck'"),
                (dict(style="tee", size="S", size_chart='{"chest": [92, 84]}'), 422, "greater than its max"),
                (dict(style="tee", size="S", size_chart='{"chest": 500}'), 422, "plausible range"),
                (dict(style="tee"), 422, "needs a size label"),
                (dict(style="Tee!", size="S"), 422, "style must be a short id")):
            r = upload(**form)
            assert r.status_code == status and words in r.json()["detail"], (form, r.text)
        assert c.get("/api/garments").json() == {"garments": []}
        r = upload(style="tee", size="S", size_chart='{"chest": [84, 92], "waist": 74}')
        assert r.status_code == 201, r.text
        assert (r.json()["style"], r.json()["size"], r.json()["chart"]) == ("tee", "S", {"chest": [84.0, 92.0],
                                                                                       "waist": [74.0, 74.0]})
        assert c.get("/api/styles").json() == [{"style": "tee", "name": "Tee", "category": "top", "sizes": [
            {"size": "S", "garment_id": r.json()["id"], "chart": {"chest": [84.0, 92.0], "waist": [74.0, 74.0]}}]}]


def test_ingest_command_takes_style_and_chart(tmp_path, files, capsys):
    path = str(files["trousers", "M"])
    base = ["ingest", path, "--units", "m", "--data-dir", str(tmp_path)]
    assert main([*base, "--style", "trousers", "--size", "M", "--size-chart", '{"waist": [78, 86'] ) == 2
    assert "size chart is not valid JSON" in capsys.readouterr().err
    assert main([*base, "--style", "trousers", "--size", "M", "--size-chart", '{"hips": [103, 97]}']) == 2
    assert "hips min 103 cm is greater than its max 97 cm" in capsys.readouterr().err
    assert main([*base, "--style", "trousers", "--size-chart", '{"hips": 100}']) == 2
    assert "needs a size label" in capsys.readouterr().err
    assert main([*base, "--style", "trousers", "--size", "M", "--size-chart", '{"waist": [78, 86], "hips": 100}']) == 0
    assert "style trousers M" in capsys.readouterr().out
    (entry,) = Catalogue(tmp_path).list()
    assert (entry.style, entry.size, entry.chart) == ("trousers", "M", {"waist": [78.0, 86.0], "hips": [100.0, 100.0]})


# --- ease on a known garment ------------------------------------------------------------------------------


def test_a_band_too_small_that_slid_down_is_tight_not_falling_off():
    from tryon.fit.verdict import judge

    small = {"stays_up": False, "slid_cm": 15.2, "too_tight": {"torso waist": 40, "thigh_l": 12}}
    verdict, reason = judge("bottom", small, {"waist": None, "hips": None})
    assert verdict == "tight"
    assert reason == ("too tight at the waist and the left thigh: the cloth is stretched past its limit there (and it "
                      "slid 15 cm down from where it was put on)")
    large = {"stays_up": False, "slid_cm": 25.0, "too_tight": {}}
    assert judge("bottom", large, {"waist": None, "hips": None}) == (
        "falls_off", "does not stay on the hips: it slid 25 cm down from where it was put on")


def test_too_tight_is_told_from_the_shown_mesh_but_not_round_a_hand_a_foot_or_between_the_legs(data_dir):
    """The T-shirt M at rest on the M body: nothing too tight. Its shown mesh widened 30 % round the body's axis
    (every edge across the body stretched past the 15 % shear limit), its coarse mesh unchanged: too tight at the
    chest, from the shown mesh alone. Points below the ankle bones, on a hand or between the thighs are not a place to
    be sized by."""
    from tryon.sim.constraints import spring_strain
    from scipy.spatial import cKDTree

    from tryon.sim.metrics import between_sides, beyond_limb_ends, too_tight_places

    catalogue = Catalogue(data_dir)
    meta = catalogue.style("tshirt")[1]
    model = catalogue.model(meta.id)
    body = build_body(Measurements(**AT_M))
    result = drape(body, model, SimSettings())
    assert result.metrics["too_tight"] == {} and result.metrics["display_max_strain"] < 0.16
    # the shown mesh's own crossings, as the metrics count them
    from tryon.sim.collision.crossings import self_intersections
    assert result.metrics["self_crossings"] == self_intersections(result.vertices, result.faces)
    strain = spring_strain(result.coarse, model.springs, model.rest)
    on_body = np.ones(len(result.coarse), dtype=np.bool_)  # as if every point touched the body
    limits = np.asarray(SimSettings().strain_limit)
    axis = result.vertices.mean(axis=0)
    wide = result.vertices.copy()
    wide[:, [0, 2]] = axis[[0, 2]] + 1.3 * (wide[:, [0, 2]] - axis[[0, 2]])
    assert "torso chest" not in too_tight_places(result.coarse, model, strain, limits, on_body, body, result.vertices)
    assert "torso chest" in too_tight_places(result.coarse, model, strain, limits, on_body, body, wide)
    # nothing counts off the body: the same wide mesh with no point touching it
    assert too_tight_places(result.coarse, model, strain, limits, ~on_body, body, wide) == {}

    wrist, elbow = np.asarray(body.joints["wrist_l"]), np.asarray(body.joints["elbow_l"])
    along = (wrist - elbow) / np.linalg.norm(wrist - elbow)
    points = np.array([[0.1, 0.02, 0.05],  # at a foot, under the ankle bone (6.6 cm on a 170 cm body)
                       [0.1, 0.10, 0.05],  # above it, on the shin
                       wrist + 0.06 * along,  # on the hand
                       elbow,  # on the forearm
                       wrist + 0.30 * along])  # past the hand's length
    assert beyond_limb_ends(points, body).tolist() == [True, False, True, False, False]

    # cloth pinched between the thighs (a crotch seam hanging between them) is not a girth of either
    names = np.array(body.parts)[body.vertex_part]
    left, right = body.vertices[names == "thigh_l"], body.vertices[names == "thigh_r"]
    gap, nearest = cKDTree(right).query(left)
    closest = int(np.argmin(gap))
    between = 0.5 * (left[closest] + right[nearest[closest]])
    outer = left[np.argmax(left[:, 0])]  # the outside of the left thigh
    chest = np.array([0.0, body.levels["chest"], body.vertices[:, 2].max()])
    assert between_sides(np.array([between, outer, chest]), body).tolist() == [True, False, False]


# A verdict's reason in words, as ``judge`` gives them, for the recommendation's tests.
REASONS = {"tight": "too tight at the waist: the cloth is stretched past its limit there",
           "loose": "loose: 17 cm of ease at the hips (over 16 cm); stays on the hips",
           "fits": "6 cm of ease at the hips; stays on the hips",
           "falls_off": "does not stay on the hips: it slid 30 cm down from where it was put on",
           "not_draped": "not draped"}


@pytest.mark.parametrize("verdicts,slid,expected,words", [
    # trousers on a 90 cm waist, 99 cm hips: L's band a little wider than the waist rests on the hips
    (["tight", "tight", "falls_off", "fits", "not_draped"], [1, 1, 11, 2, None], "L",
     "L is the smallest size with the room of a regular fit (S, M too tight); it sits 11 cm lower than it was put on"),
    # the chart's S measured a little looser than M: S, not the larger M
    (["loose", "fits", "not_draped", "not_draped", "not_draped"], [1, 1, None, None, None], "S",
     "S is the smallest size with the room of a regular fit; it is loose: 17 cm"),
    (["tight", "tight", "tight", "tight", "loose"], [15, 14, 13, 2, 1], "XXL", "XXL is the smallest size with the room"),
    (["not_draped", "tight", "fits", "fits", "not_draped"], [None, 1, 1, 1, None], "L",
     "L is the smallest size with the room of a regular fit (M too tight); it fits"),
    (["fits", "tight", "fits", "loose", "not_draped"], [1, 1, 1, 1, None], "S", "S is the smallest size with the room"),
    (["not_draped", "not_draped", "tight", "fits", "tight"], [None, None, 1, 1, 5], "XL", "(L too tight)"),
    (["tight", "falls_off", "fits", "fits", "not_draped"], [1, 30, 2, 2, None], None,
     "no size fits: M, the smallest that is not too tight (S too tight), does not stay on"),
    (["tight", "tight", "tight", "not_draped", "not_draped"], [1, 1, 1, None, None], None,
     "every size draped is too tight: the largest, L, is"),
])
def test_without_a_chart_the_answer_is_the_smallest_size_not_too_tight(verdicts, slid, expected, words):
    from tryon.fit.verdict import recommend

    size, why = recommend(SIZES, verdicts, [REASONS[v] for v in verdicts], slid)
    assert size == expected and words in why, why


def test_a_larger_body_never_gets_a_smaller_size():
    """Whatever the sizes' verdicts, a body that makes more sizes tight (a larger body) never gets a smaller
    recommendation: seeded random verdicts, and the same with the tight ones extended upwards."""
    import random

    from tryon.fit.verdict import recommend

    rng = random.Random(7)
    sizes = ["S", "M", "L", "XL", "XXL"]
    for _ in range(500):
        verdicts = [rng.choice(["tight", "fits", "loose", "falls_off", "not_draped"]) for _ in sizes]
        slid = [rng.choice([2.0, 12.0, 30.0]) for _ in sizes]
        k = rng.randrange(len(sizes))
        larger = ["tight" if i <= k and v != "not_draped" else v for i, v in enumerate(verdicts)]
        a, _ = recommend(sizes, verdicts, verdicts, slid)
        b, _ = recommend(sizes, larger, larger, slid)
        if a is not None and b is not None:
            assert sizes.index(b) >= sizes.index(a), (verdicts, larger, a, b)


@pytest.mark.parametrize("verdicts,chart,preference,expected,words", [
    # the chart's size that fits is the answer, whatever a smaller size's drape says
    (["fits", "fits", "fits", "not_draped", "not_draped"], 1, "regular", "M", "M: the chart's size for you is M; M fits"),
    # a slim fit: a size under, if it is not too tight; a relaxed one: a size over, if it stays on
    (["fits", "fits", "fits", "not_draped", "not_draped"], 1, "slim", "S", "M, S for a slim fit; S fits"),
    (["tight", "fits", "fits", "not_draped", "not_draped"], 1, "slim", "M", "S is too tight at the waist"),
    (["fits", "fits", "fits", "not_draped", "not_draped"], 1, "relaxed", "L", "M, L for a relaxed fit; L fits"),
    (["not_draped", "fits", "falls_off", "not_draped", "not_draped"], 1, "relaxed", "M", "L does not stay on"),
    # the chart's size too tight: the next larger that is not; loose: a smaller one that fits
    (["not_draped", "tight", "fits", "fits", "not_draped"], 1, "regular", "L", "M is too tight at the waist"),
    (["not_draped", "fits", "loose", "not_draped", "not_draped"], 2, "regular", "M", "L is loose: 17 cm"),
    # off the chart's top row: its largest size
    (["not_draped", "not_draped", "not_draped", "tight", "fits"], 4, "relaxed", "XXL", "XXL fits"),
])
def test_with_a_chart_the_answer_is_the_charts_size_moved_by_the_preference_and_the_drape(
        verdicts, chart, preference, expected, words):
    from tryon.fit.verdict import recommend

    slid = [30.0 if v == "falls_off" else 1.0 for v in verdicts]
    size, why = recommend(SIZES, verdicts, [REASONS[v] for v in verdicts], slid, chart, preference)
    assert size == expected and words in why, why


def test_a_larger_body_on_the_chart_never_gets_a_smaller_size_and_slim_is_never_larger_than_relaxed():
    """Seeded random verdicts: a larger chart size with more sizes tight never gets a smaller answer; for one
    body, slim <= regular <= relaxed."""
    import random

    from tryon.fit.verdict import recommend

    rng = random.Random(11)
    sizes = ["S", "M", "L", "XL", "XXL"]
    for _ in range(500):
        tight_below = rng.randrange(len(sizes))  # a smaller size is tighter: the tight ones come first
        verdicts = ["tight" if i < tight_below else rng.choice(["fits", "fits", "loose", "falls_off"])
                    for i in range(len(sizes))]
        slid = [30.0 if v == "falls_off" else 1.0 for v in verdicts]
        chart = rng.randrange(len(sizes) - 1)
        k = rng.randrange(chart + 1)
        larger = ["tight" if i <= k else v for i, v in enumerate(verdicts)]
        answers = [recommend(sizes, verdicts, verdicts, slid, chart, p)[0] for p in ("slim", "regular", "relaxed")]
        order = [sizes.index(a) for a in answers if a is not None]
        assert order == sorted(order), (verdicts, chart, answers)
        a, _ = recommend(sizes, verdicts, verdicts, slid, chart)
        b, _ = recommend(sizes, larger, larger, slid, chart + 1)
        if a is not None and b is not None:
            assert sizes.index(b) >= sizes.index(a), (verdicts, larger, chart, a, b)


def test_a_knit_top_a_little_shorter_than_the_chest_is_fitted_a_woven_one_is_tight():
    from tryon.fit.ease import Girth
    from tryon.fit.verdict import judge

    metrics = {"stays_up": True, "slid_cm": 0.5, "too_tight": {}}
    short = {"chest": Girth("chest", 1.3, body_cm=112.0, garment_cm=114.0, cloth_cm=109.3)}  # 2.7 cm, 2.4 %
    assert judge("dress", metrics, short, comfort_stretch=0.03)[0] == "fits"
    verdict, reason = judge("top", metrics, short, comfort_stretch=0.0)
    assert verdict == "tight" and reason == "too tight at the chest: its cloth, unstretched, is 3 cm shorter than the chest"
    shorter = {"chest": Girth("chest", 1.3, body_cm=112.0, garment_cm=113.0, cloth_cm=107.0)}  # 5 cm, 4.5 %
    assert judge("dress", metrics, shorter, comfort_stretch=0.03) == (
        "tight", "too tight at the chest: its cloth, unstretched, is 5 cm shorter than the chest, more than the 3 cm "
                 "its fabric takes fitted")


def test_a_larger_size_with_less_room_is_noted_with_why():
    from tryon.fit.advice import SizeAdvice, ease_notes

    def size(name, waist, hips, slid):
        return SizeAdvice(name, name, "fits", "", cloth_ease_cm={"waist": waist, "hips": hips}, slid_cm=slid)

    notes = ease_notes([size("S", 4.0, 3.0, 0.0), size("M", 3.5, 0.5, 6.0), size("L", 6.0, 4.0, 6.5),
                        SizeAdvice("XL", "XL", "not_draped", "")])
    assert notes == ["M leaves less room at the hips than S (+0.5 against +3.0 cm): it sits 6 cm lower on the body, "
                     "where the body is wider"]
    assert ease_notes([size("S", 4.0, 3.0, 0.0), size("M", 1.0, 3.0, 0.5)]) == [
        "M leaves less room at the waist than S (+1.0 against +4.0 cm): it sits no lower: its drape, not its size, "
        "leaves less cloth round the body there"]


def test_length_in_words_from_where_the_ends_lie():
    from tryon.fit.verdict import length_notes

    assert length_notes({"sleeve_l": 7.3, "sleeve_r": 2.0, "hem": 21.2}) == [
        "too long: the sleeves end 7 cm past the wrists", "too long: the hem ends 21 cm below the hips"]
    assert length_notes({"leg_l": -6.4, "leg_r": -5.5}) == ["too long: the trouser legs end 6 cm below the ankles"]
    assert length_notes({"leg_l": 3.6, "leg_r": 1.0}) == ["too short: the trouser legs end 4 cm above the ankles"]
    assert length_notes({"sleeve_l": -6.2, "hem": -9.0}) == [
        "too short: the sleeves end 6 cm short of the wrists", "too short: the hem ends 9 cm above the hips"]
    assert length_notes({"sleeve_l": 1.0, "leg_l": 0.0, "hem": 12.0}) == [] and length_notes({}) == []


def test_the_same_trousers_reach_the_floor_on_a_short_person_and_bare_the_ankles_on_a_tall_one(data_dir):
    """Trousers M on M girths at 160 and 190 cm: the legs end below the ankle bone on the short person (too
    long), above it on the tall one (too short); the advice says so after its verdict."""
    catalogue = Catalogue(data_dir)
    m = catalogue.style("trousers")[1]
    model = catalogue.model(m.id)
    out = {}
    for height in (160, 190):
        body = build_body(Measurements(**{**AT_M, "height": height}))
        result = drape(body, model, SimSettings())
        out[height] = advise_size("M", m.id, "bottom", body, result.vertices, result.faces, model.vertices,
                                  result.metrics)
    short, tall = out[160], out[190]
    assert set(short.ends_cm) == {"leg_l", "leg_r"} and max(short.ends_cm.values()) < -5.0
    assert short.length == [f"too long: the trouser legs end {-min(short.ends_cm.values()):.0f} cm below the ankles"]
    assert short.reason.endswith(short.length[0])
    assert min(tall.ends_cm.values()) > 3.0 and tall.length[0].startswith("too short: the trouser legs end")


def test_long_sleeves_reach_over_the_hands_of_a_short_person_and_a_tshirt_has_only_its_hem_measured(data_dir, tmp_path):
    body = build_body(Measurements(**{**AT_M, "height": 160}))
    catalogue = Catalogue(tmp_path / "data")
    name, category = GARMENTS["longsleeve"]
    sleeve = catalogue.ingest(obj_text(garment_mesh("longsleeve", "M"), "longsleeve M").encode(), filename="ls.obj",
                              name=f"{name} M", category=category, units="m")
    ends = drape(body, catalogue.model(sleeve.id), SimSettings()).metrics["ends_cm"]
    assert set(ends) == {"sleeve_l", "sleeve_r", "hem"} and min(ends["sleeve_l"], ends["sleeve_r"]) > 5.0
    assert "too long: the sleeves end" in length_notes(ends)[0]
    shirt = Catalogue(data_dir).style("tshirt")[1]
    assert set(drape(body, Catalogue(data_dir).model(shirt.id), SimSettings()).metrics["ends_cm"]) == {"hem"}


def test_ease_of_a_tube_of_known_girth_around_a_known_body():
    """A straight tube around the body's waist and hips, its sections 8 cm longer than the body's hips: its
    tape ease is its girth minus the body's at each level, within 1 cm."""
    body = build_body(Measurements(**AT_M))
    girth = (AT_M["hips"] + 8) / 100.0
    a, b = half_axes(girth)
    n, rows = 96, 12
    theta = 2 * np.pi * np.arange(n) / n
    ys = np.linspace(body.levels["hips"] - 0.08, body.levels["waist"] + 0.06, rows)
    torso = np.unique(body.faces[body.face_part == body.parts.index("torso")])
    rings = []
    for y in ys:
        near = torso[np.abs(body.vertices[torso, 1] - y) < 0.02]
        cx, cz = body.vertices[near][:, [0, 2]].mean(axis=0)
        rings.append(np.column_stack([cx + a * spow(np.cos(theta)), np.full(n, y), cz + b * spow(np.sin(theta))]))
    vertices = np.concatenate(rings)
    k = np.arange(n)
    faces = np.concatenate([np.concatenate([np.column_stack([r * n + k, r * n + (k + 1) % n, (r + 1) * n + k]),
                                            np.column_stack([(r + 1) * n + k, r * n + (k + 1) % n,
                                                             (r + 1) * n + (k + 1) % n])])
                            for r in range(rows - 1)])
    polygon = float(np.linalg.norm(np.diff(rings[0][:, [0, 2]], axis=0, append=rings[0][:1, [0, 2]]), axis=1).sum())
    measured = measure_ease(body, vertices, faces, vertices, "bottom")
    for name in ("waist", "hips"):
        g = measured[name]
        assert g.level_m == pytest.approx(body.levels[name])
        assert g.body_cm == pytest.approx(body.achieved[name], abs=0.3)
        assert g.ease_cm == pytest.approx(100 * polygon - body.achieved[name], abs=1.0)
        assert g.cloth_ease_cm == pytest.approx(g.ease_cm, abs=0.05)  # unstretched: cloth = tape
    # the same tube stretched 10 % around: its cloth is 10 % shorter than its tape
    wide = vertices.copy()
    centre = wide.mean(axis=0)
    wide[:, [0, 2]] = centre[[0, 2]] + 1.1 * (wide[:, [0, 2]] - centre[[0, 2]])
    g = measure_ease(body, wide, faces, vertices, "bottom")["hips"]
    assert g.cloth_cm == pytest.approx(g.garment_cm / 1.1, rel=0.01)


# --- POST /api/fit ----------------------------------------------------------------------------------------


def test_a_person_at_the_m_rows_centre_gets_m(client):
    pool = get_pool(client.app)
    before = pool.stats()["submitted"]
    r = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M})
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["style"] == "tshirt" and out["recommended"] == "M", out
    assert out["preference"] == "regular" and out["reason"].startswith("M: the chart's size for you is M; M fits")
    sizes = {s["size"]: s for s in out["sizes"]}
    assert [s["size"] for s in out["sizes"]] == SIZES
    styles = {s["style"]: s for s in client.get("/api/styles").json()}
    assert [s["garment_id"] for s in out["sizes"]] == [s["garment_id"] for s in styles["tshirt"]["sizes"]]
    # S leaves a little room: not too tight, a slim fit (below); the chart's M is the regular answer
    assert sizes["S"]["verdict"] == "fits" and 0.0 < sizes["S"]["cloth_ease_cm"]["chest"] < 3.0
    m = sizes["M"]
    assert m["verdict"] == "fits" and m["stays_up"] is True and m["too_tight"] == {}
    assert 3.0 < m["ease_cm"]["chest"] < 16.0 and m["max_strain"] > 0
    assert m["reason"] == f"{round(m['ease_cm']['chest'])} cm of ease at the chest; stays on the shoulders"
    for size in ("XL", "XXL"):  # two and three sizes from the person's on the chart
        assert sizes[size]["verdict"] == "not_draped" and "sizes from yours" in sizes[size]["reason"]
        assert sizes[size]["ease_cm"] == {} and sizes[size]["stays_up"] is None
    assert out["wall_seconds"] > 0
    stats = pool.stats()  # S, M and L draped on the pool, at most its workers at once; nothing left running
    assert stats["submitted"] - before == 3 and stats["running"] == 0 and stats["waiting"] == 0

    # the page then shows M's drape without simulating again, with the advice's verdict for it: one verdict
    t = client.post("/api/tryon", json={"garment_id": m["garment_id"], "measurements": AT_M})
    assert t.status_code == 200 and t.json()["metrics"]["cached"] is True
    assert (t.json()["metrics"]["verdict"], t.json()["metrics"]["verdict_reason"]) == ("fits", m["reason"])
    s = client.post("/api/tryon", json={"garment_id": sizes["S"]["garment_id"], "measurements": AT_M}).json()
    assert (s["metrics"]["verdict"], s["metrics"]["verdict_reason"]) == ("fits", sizes["S"]["reason"])
    # ... and the advice again comes from the cache too
    again = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M}).json()
    assert again["sizes"] == out["sizes"] and again["wall_seconds"] >= 0
    assert pool.stats()["submitted"] - before == 3  # nothing draped again


def test_the_fit_preference_moves_the_answer_a_size_where_the_drape_allows(client):
    """At the M row's centre: slim S (not too tight: a little room), relaxed L (stays on, not loose); the drapes
    are the regular answer's (S, M and L were draped for it: nothing drapes again)."""
    regular = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M}).json()
    slim = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M, "preference": "slim"}).json()
    relaxed = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M, "preference": "relaxed"}).json()
    assert (slim["recommended"], regular["recommended"], relaxed["recommended"]) == ("S", "M", "L")
    assert slim["preference"] == "slim" and "S for a slim fit" in slim["reason"]
    assert relaxed["sizes"] == regular["sizes"] == slim["sizes"]
    r = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M, "preference": "baggy"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "preference"]


def test_two_sizes_smaller_is_tight_and_the_trousers_follow_their_chart(client, data_dir):
    out = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_L}).json()
    assert out["recommended"] == "L", out
    assert [s["verdict"] for s in out["sizes"]][1:3] == ["fits", "fits"]  # M: a slim fit
    assert out["sizes"][0]["verdict"] == "not_draped"  # S: two sizes under L on the chart, so not draped ...
    catalogue = Catalogue(data_dir)
    s = catalogue.style("tshirt")[0]
    model = catalogue.model(s.id)
    body = build_body(Measurements(**AT_L))
    result = drape(body, model, SimSettings())  # ... but when it is, it is tight
    advice = advise_size("S", s.id, "top", body, result.vertices, result.faces, model.vertices, result.metrics)
    assert advice.verdict == "tight" and advice.reason.startswith("too tight at the chest: ")
    assert advice.cloth_ease_cm["chest"] < 0
    trousers = client.post("/api/fit", json={"style": "trousers", "measurements": AT_M}).json()
    assert trousers["recommended"] == "M", trousers
    s = trousers["sizes"][0]
    assert s["verdict"] == "tight" and s["too_tight"] and "too tight at the waist" in s["reason"]
    assert set(trousers["sizes"][1]["ease_cm"]) == {"waist", "hips"}


def test_fit_errors(client):
    r = client.post("/api/fit", json={"style": "gown", "measurements": AT_M})
    assert r.status_code == 404 and "no style 'gown'" in r.json()["detail"]
    r = client.post("/api/fit", json={"style": "tshirt", "measurements": {**AT_M, "chest": 300}})
    assert r.status_code == 422 and "measurements.chest=300 cm is outside" in r.text
    r = client.post("/api/fit", json={"style": "tshirt", "measurements": {"height": 170, "chest": 96, "waist": 82}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "measurements", "hips"]
    r = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M, "pose": {"arm_angle": 120}})
    assert r.status_code == 422 and "pose.arm_angle" in r.text
    r = client.post("/api/fit", json={"style": "tshirt", "measurements": AT_M, "size": "M"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "size"]


def test_a_full_pool_answers_503_with_retry_after(data_dir):
    app = create_app(Settings(data_dir=data_dir, sim_workers=1, sim_queue=0))
    with TestClient(app) as c:
        release = threading.Event()
        busy = get_pool(app).submit(release.wait)  # another shopper's try-on holds the only place
        try:
            r = c.post("/api/fit", json={"style": "tshirt", "measurements": {**AT_M, "height": 171}})
            assert r.status_code == 503 and "busy" in r.json()["detail"]
            assert int(r.headers["retry-after"]) > 0
        finally:
            release.set()
            busy.result(timeout=10)


# --- tryon fit --------------------------------------------------------------------------------------------


def test_fit_command_prints_the_advice_as_a_table(data_dir, capsys):
    assert main(["fit", "tshirt", "--height", "170", "--chest", "96", "--waist", "82", "--hips", "100",
                 "--data-dir", str(data_dir)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:4] == ["size", "verdict", "chest", "ease"]
    assert [line.split()[:2] for line in out[1:6]] == [["S", "fits"], ["M", "fits"], ["L", "fits"],
                                                       ["XL", "not_draped"], ["XXL", "not_draped"]]
    assert out[6].startswith("recommended: M (M: the chart's size for you is M; M fits")
    assert main(["fit", "tshirt", "--height", "170", "--chest", "96", "--waist", "82", "--hips", "100",
                 "--fit", "slim", "--data-dir", str(data_dir)]) == 0
    assert "recommended: S (S: the chart's size for you is M, S for a slim fit; S fits" in capsys.readouterr().out


def test_fit_command_errors(data_dir, tmp_path, capsys):
    base = ["--height", "170", "--chest", "96", "--waist", "82", "--hips", "100"]
    assert main(["fit", "gown", *base, "--data-dir", str(data_dir)]) == 2
    err = capsys.readouterr().err
    assert "no style 'gown'" in err and "tshirt, trousers" in err
    assert main(["fit", "tshirt", *base[:-1], "300", "--data-dir", str(data_dir)]) == 2
    assert "hips=300 cm is outside [75, 150] cm" in capsys.readouterr().err
    assert main(["fit", "tshirt", *base, "--data-dir", str(tmp_path / "empty")]) == 2
    assert "no catalogue in" in capsys.readouterr().err
