"""``tryon bench --quick``: runs once per module and writes the report files with finite numbers.

No timing assertions (the machine is shared); the benchmark's numbers are checked for shape, finiteness
and the invariants that do not depend on speed. The tests that run it are ``slow`` (left out of the fast lane).
"""

from __future__ import annotations

import json
import math
import struct
import zlib
from types import SimpleNamespace

import pytest

from tryon.cli import main

SECTIONS = {"table1", "table2", "table3", "fit", "poses", "outfits", "live", "motion", "pareto", "simplify", "peers", "stability",
            "scaling", "scale", "sizes", "selfcontact"}
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    code = main(["bench", "--quick", "--out", str(out)])
    report = json.loads((out / "bench.json").read_text())
    return out, code, report


def _numbers(value):
    """Every int/float leaf of a JSON value."""
    if isinstance(value, bool):
        return
    if isinstance(value, (int, float)):
        yield value
    elif isinstance(value, dict):
        for v in value.values():
            yield from _numbers(v)
    elif isinstance(value, list):
        for v in value:
            yield from _numbers(v)


def _section(report, name):
    return next(s for s in report["sections"] if s["name"] == name)


@pytest.mark.slow
def test_exit_code_and_files(bench):
    out, code, report = bench
    failed = {s["name"]: s["error"] for s in report["sections"] if s["status"] == "failed"}
    assert code == (1 if failed else 0)
    assert not failed, failed
    assert (out / "bench.md").read_text().startswith("# tryon bench")
    assert {s["name"] for s in report["sections"]} == SECTIONS


@pytest.mark.slow
def test_json_numbers_are_finite(bench):
    _, _, report = bench
    numbers = list(_numbers(report))
    assert len(numbers) > 50
    assert all(math.isfinite(x) for x in numbers)


@pytest.mark.slow
def test_sections_carry_their_figures(bench):
    _, _, report = bench
    sizes = _section(report, "sizes")["data"]
    for style, by in sizes["preferences"].items():  # slim never a larger size, relaxed never a smaller one
        assert by["slim"]["larger"] == 0 and by["relaxed"]["smaller"] == 0
        assert 0 < sum(by["slim"].values()) <= sizes["styles"][style]["people"]
        assert sizes["advice_s_median"][style] > 0 and sizes["tryon_s_median"][style] > 0  # one try-on timed too
    t1 = _section(report, "table1")["data"]["ours"][0]
    assert 0 < t1["simplified"] < t1["vertices"]
    assert t1["collision_ms_full"] > 0 and t1["collision_ms_simplified"] > 0
    t2 = _section(report, "table2")["data"]
    assert set(t2["methods"]) == {"angle", "area", "barycentric"}
    # the three tests decide the same random hits alike (ties on edges aside)
    assert min(t2["agreement"].values()) > 0.999
    fit = _section(report, "fit")["data"]["drapes"]
    assert [d["body"] for d in fit] == ["small", "medium", "large"]
    # the main garment (T-shirt M) on the three bodies: no penetration, at rest, springs within the target
    assert all(d["penetrating"] == 0 and d["rest"] and d["over"] == 0 for d in fit), fit
    assert all(d["stays_up"] and d["slid_cm"] < 10.0 for d in fit), fit  # on the shoulders on every body
    # every frame a caller is shown watched against the body: millimetres at most (issue 26 asks for 2); the
    # start-up, where the body is grown into the garment from half its girth, is not shown (cm deep)
    assert all(0.0 <= d["frame_depth_mm"] < 10.0 for d in fit), fit
    # the main garment with the arms at 10 degrees and the elbows bent 90: sleeves round the arms, every target met
    poses = _section(report, "poses")["data"]["drapes"]
    assert [d["pose"] for d in poses] == [{"arm_angle": 10.0}, {"elbow_bend": 90.0}]
    assert all(d["met"] and d["on_limbs"] for d in poses), poses
    pareto = _section(report, "pareto")["data"]
    assert len(pareto["points"]) >= 2 and pareto["pick"] in pareto["points"]
    assert all(p["rms_mm"] >= 0 for p in pareto["points"])
    ball = _section(report, "peers")["data"]["cloth_on_ball"]["1024"]
    ours = [r for r in ball if r["engine"] == "ours (1 thread)"][0]
    assert ours["frames"] == 300 and ours["finite"]
    # live re-posing through a real server: the T-shirt M carried to a named pose, then in a session of its own
    # through a change of 30 degrees, each at rest with nothing in the body and both sleeves on the arms, a first
    # frame before the done (tests/test_ws_live.py carries it through three more)
    live = _section(report, "live")["data"]["updates"]
    assert [d["pose"] for d in live] == ["hands_on_hips", "30 degrees 1"]
    assert [d["thirty_degrees"] for d in live] == [False, True]
    assert all(d["rest"] and d["penetrating"] == 0 and d["on_limbs"] for d in live), live
    assert all(0 < d["first_frame_s"] < d["done_s"] for d in live), live
    # and a slider dragged (30 updates, not waiting for any done): frames came while it moved, the updates were
    # coalesced (one done: the last update's; the others gave way), the garment at rest on the arms
    drag = _section(report, "live")["data"]["drags"]
    assert len(drag) == 1 and drag[0]["updates"] == 30 and drag[0]["frames"] > 0, drag
    assert 1 <= drag[0]["reposes"] <= 30 and drag[0]["dones"] == 1, drag
    assert drag[0]["penetrating"] == 0 and drag[0]["on_limbs"], drag
    scaling = _section(report, "scaling")["data"]
    assert [r["vertices"] for r in scaling["garment"]] == sorted(r["vertices"] for r in scaling["garment"])
    # every step is timed, the start-up's too (a tube put on tangled with the body grows it for 20 steps; handed
    # only the shown steps, the timer had none and wrote null)
    timed = [r["ms_per_step"] for r in scaling["garment"] + scaling["body"]]
    assert all(t is not None and t > 0.0 for t in timed), timed
    # the perf T-shirt draped to rest as a try-on runs it (issue 26's 0.15 s target is read from this row)
    rest = scaling["to_rest"]
    assert rest[0]["vertices"] > 7000 and rest[0]["particles"] < rest[0]["vertices"], rest
    assert rest[0]["rest_reached"] and rest[0]["wall_s_1"] > 0.0, rest


def _png_ok(data: bytes) -> bool:
    """Signature, an IHDR chunk with its CRC, positive size, and an IEND at the end."""
    if not data.startswith(PNG_SIGNATURE):
        return False
    length, kind = struct.unpack(">I4s", data[8:16])
    if kind != b"IHDR" or length != 13:
        return False
    ihdr = data[16:29]
    (crc,) = struct.unpack(">I", data[29:33])
    width, height = struct.unpack(">II", ihdr[:8])
    return zlib.crc32(b"IHDR" + ihdr) == crc and width > 0 and height > 0 and data[-8:-4] == b"IEND"


@pytest.mark.slow
def test_plots_are_valid_pngs(bench):
    out, _, report = bench
    plots = [p for s in report["sections"] for p in s["plots"]]
    assert {"pareto.png", "peers.png", "scaling.png"} <= set(plots)
    for name in plots:
        assert _png_ok((out / name).read_bytes()), name


def test_a_failing_section_is_reported_and_isolated(tmp_path):
    from tryon.bench.common import Context, SkipSection, run_section

    ctx = Context(tmp_path, quick=True, stress=False, log=lambda msg: None)

    def broken(ctx, sec):
        raise ValueError("kernel said no")

    def absent(ctx, sec):
        raise SkipSection("optional input missing")

    failed = run_section("x", "X", broken, ctx)
    skipped = run_section("y", "Y", absent, ctx)
    assert failed.status == "failed" and "kernel said no" in failed.error
    assert skipped.status == "skipped" and skipped.error == "optional input missing"


@pytest.mark.slow
def test_a_missing_peer_is_a_note_not_a_failure(bench, monkeypatch, tmp_path):
    """The peers section with no peer engine: the quick run's own when none is installed (as with the test extra
    alone), else one run with them hidden."""
    from tryon.bench import peers
    from tryon.bench.common import Context, run_section

    if all(peers.peer_available(engine) for engine in peers.PEERS):
        sec = _section(bench[2], "peers")
        assert sec["status"] == "ok", sec["error"]
        sec = SimpleNamespace(**sec)  # its fields as attributes, as run_section's answer has them
    else:
        monkeypatch.setattr(peers, "peer_available", lambda engine: f"{engine} is not installed")
        ctx = Context(tmp_path, quick=True, stress=False, log=lambda msg: None)
        sec = run_section("peers", "Peer engines", peers.run, ctx)
        assert sec.status == "ok", sec.error
    assert any("taichi skipped: taichi" in n and "not installed" in n for n in sec.notes), sec.notes
    rows = sec.data["cloth_on_ball"]["1024"]
    assert [r["engine"] for r in rows] == ["ours (1 thread)"]  # 1,024 points: one block, one thread
    assert sec.data["headline"] == []  # no peer, no ratio
    # ours at the bound instead (no peer to match): the fast projection of the strain limits, then more
    # substeps a step, until the cloth's stretch over all 300 frames is within its limit + 1 %, each try stretching
    # less than the one before; then 3/4 of the substeps while they still meet it; the cheapest that met is ours
    (quality,) = sec.data["equal_quality"]
    assert quality["target_target"].startswith("the bound") and quality["target_stretch"] == pytest.approx(0.11)
    tried = quality["tried"]
    assert tried[0][:2] == [16, 0] and tried[0][2] > 0.11 and tried[1][:2] == [16, 4]
    first = next(i for i, t in enumerate(tried) if t[2] <= 0.11 + 1e-9)
    assert [t[2] for t in tried[:first + 1]] == sorted((t[2] for t in tried[:first + 1]), reverse=True)
    assert all(t[0] == int(0.75 * u[0]) and t[1] == u[1] for u, t in zip(tried[first:], tried[first + 1:]))
    assert all(t[2] <= 0.11 + 1e-9 for t in tried[first:-1])  # the fewer substeps go on while they meet it
    met = [t for t in tried if t[2] <= 0.11 + 1e-9]
    assert [quality["substeps"], quality["projection_steps"]] in [t[:2] for t in met]
    assert quality["frame_ms"] == min(t[3] for t in met)
    assert quality["met"] and quality["max_stretch"] <= 0.11 + 1e-9 and quality["frames"] == 300


def ball_row(stretch, frame_ms):
    """One of our ball runs, as ``run_sphere`` summarises it (300 frames run)."""
    return {"frames": 300, "max_stretch": stretch, "max_penetration_mm": 0.5, "frame_ms_median": frame_ms,
            "final_stretch": stretch}


def test_the_equal_quality_search_does_not_start_a_try_it_cannot_finish():
    """A try whose run would last longer than the cap (estimated from the last one, its cost growing with the
    substeps) is not started: the search ends there, not met, and says why; at two threads the summary says so."""
    from tryon.bench.equal_quality import at_equal_quality

    target = {"target": "taichi (2 threads)", "stretch": 0.11, "penetration_mm": 2.0, "frame_ms": 100.0}
    runs = []

    def run(settings, steps):
        runs.append((steps, settings.substeps))
        # 300 frames of 1 s: 300 s a try at 16 substeps and 4 steps a frame; fewer steps stretch more
        return ball_row(0.2 + 0.1 / steps, 1000.0 * settings.substeps / 16 * steps / 4)

    out = at_equal_quality(200, ball_row(0.3, 500.0), target, run, threads=2, max_seconds=400.0, steps=4)
    # one and two steps a frame first (cheaper, not met); the default took 150 s; the projection at 16 substeps
    # ~150 s: run; 32 substeps ~600 s: not started
    assert runs == [(1, 16), (2, 16), (4, 16)] and not out["met"] and out["threads"] == 2
    assert out["stopped"].startswith("32 substeps a step + 4 projection steps would run ~600 s")
    assert [t[:2] for t in out["tried"]] == [[16, 4], [16, 4], [16, 0], [16, 4]]
    assert [t[4] for t in out["tried"]] == [1, 2, 4, 4]


def test_the_equal_quality_search_takes_fewer_steps_a_frame_where_they_meet_the_target():
    """Where one step a frame with the projection meets the target, it is the answer: cheaper than the default's
    two, and nothing dearer is run."""
    from tryon.bench.equal_quality import at_equal_quality

    target = {"target": "taichi (1 thread)", "stretch": 0.18, "penetration_mm": 2.0, "frame_ms": 26.0}
    runs = []

    def run(settings, steps):
        runs.append((steps, settings.substeps, settings.projection_steps))
        # fewer substeps stretch more: 12 still meets the target, 9 does not
        return ball_row(0.16 if settings.substeps >= 12 else 0.2, 13.0 * settings.substeps / 16)

    out = at_equal_quality(100, ball_row(0.26, 26.0), target, run, steps=2)
    # one step a frame at the default substeps meets it; then 3/4 of the substeps while they do (the dearer
    # settings are never run)
    assert runs == [(1, 16, 4), (1, 12, 4), (1, 9, 4)]
    assert out["met"] and out["steps_per_frame"] == 1 and out["projection_steps"] == 4 and out["substeps"] == 12
    assert out["speedup"] == pytest.approx(26.0 / 9.75)


def test_bad_out_or_section_is_refused_before_running(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    assert main(["bench", "--quick", "--only", "table1", "--out", str(blocker / "out")]) == 2
    assert "cannot write to --out" in capsys.readouterr().err
    assert main(["bench", "--quick", "--only", "tabel1", "--out", str(tmp_path / "out")]) == 2
    assert "unknown section 'tabel1'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_fit_with_fewer_substeps_says_so(tmp_path, capsys):
    assert main(["bench", "--quick", "--only", "fit", "--substeps", "0", "--out", str(tmp_path / "bad")]) == 2
    assert "--substeps must be 1 to 16, got 0" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
    out = tmp_path / "out"
    assert main(["bench", "--quick", "--only", "fit", "--substeps", "8", "--out", str(out)]) == 0
    report = json.loads((out / "bench.json").read_text())
    fit = _section(report, "fit")
    assert (fit["data"]["substeps"], fit["data"]["passes"]) == (8, 8)
    assert fit["headline"][0].startswith("fit, 8 substeps: 3 drapes")
    assert "8 substeps of one pass a step" in (out / "bench.md").read_text()
    assert report["command"].endswith("--substeps 8")


def test_fit_with_the_fast_projection_says_so(tmp_path, capsys):
    assert main(["bench", "--quick", "--only", "fit", "--projection", "9", "--out", str(tmp_path / "bad")]) == 2
    assert "--projection must be 1 to 8, got 9" in capsys.readouterr().err
    out = tmp_path / "out"
    assert main(["bench", "--quick", "--only", "fit", "--projection", "4", "--out", str(out)]) == 0
    report = json.loads((out / "bench.json").read_text())
    fit = _section(report, "fit")
    assert fit["data"]["projection_steps"] == 4 and fit["data"]["substeps"] == 16
    assert fit["headline"][0].startswith("fit, 4 projection steps: 3 drapes")
    assert "4 Newton steps of the fast projection a step" in (out / "bench.md").read_text()
    assert report["command"].endswith("--projection 4")
    # the T-shirt M still drapes as a try-on must: at rest, nothing in the body, sleeves round the arms
    assert all(d["rest"] and d["penetrating"] == 0 and d["on_limbs"] for d in fit["data"]["drapes"])


@pytest.mark.slow
def test_motion_with_more_sequences_says_so(tmp_path, capsys):
    assert main(["bench", "--quick", "--only", "motion", "--sequences", "21", "--out", str(tmp_path / "bad")]) == 2
    assert "--sequences must be 1 to 20, got 21" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
    out = tmp_path / "out"
    assert main(["bench", "--quick", "--only", "motion", "--sequences", "2", "--out", str(out)]) == 0
    report = json.loads((out / "bench.json").read_text())
    motion = _section(report, "motion")
    assert motion["data"]["mode"] == "quick, 2 sequences" and motion["data"]["sequences"] == 2
    assert motion["data"]["all"]["settles"] == 2 * 2 * 3  # two garments, two sequences of three poses
    assert "x 2 random sequences of 3 poses" in motion["headline"][0]
    assert report["command"].endswith("--sequences 2")


@pytest.mark.slow
def test_the_figures_page_is_written_from_bench_json(bench, tmp_path, capsys):
    out, _, report = bench
    page = tmp_path / "docs" / "benchmarks.md"
    assert main(["bench", "--from", str(out / "bench.json"), "--page", str(page)]) == 0
    text = page.read_text()
    assert text.startswith("# Benchmarks") and "bench.json" in text
    for s in report["sections"]:
        assert f"Reproduce: `tryon bench --only {s['name']}`" in text
        for h in s["headline"]:
            assert f"- {h}" in text  # the run's own figures, not retyped
        for name in s["plots"]:
            assert f"![{name}](bench/{name})" in text
            assert (page.parent / "bench" / name).read_bytes() == (out / name).read_bytes()
    assert main(["bench", "--from", str(out / "bench.json")]) == 2
    assert "--from needs --page" in capsys.readouterr().err
    assert main(["bench", "--from", str(tmp_path / "none.json"), "--page", str(page)]) == 2
    assert "cannot read" in capsys.readouterr().err


@pytest.mark.slow
def test_outfits_section_drapes_a_top_over_a_bottom(bench):
    """Quick mode: the T-shirt over the trousers on the medium body, tucked out and in; each row has the
    outfit's figures and its time against the two single drapes."""
    _, _, report = bench
    rows = _section(report, "outfits")["data"]["outfits"]
    assert [(r["top"], r["bottom"], r["tuck"]) for r in rows] == [("T-shirt M", "Trousers M", "out"),
                                                                   ("T-shirt M", "Trousers M", "in")]
    for r in rows:
        assert r["steps"] > 0 and r["wall_s"] > 0 and r["single_sum_s"] > 0
        assert r["cost_ratio"] == pytest.approx(r["wall_s"] / r["single_sum_s"])
        assert r["layer_penetrating"] >= 0 and r["penetrating"] >= 0
        assert math.isfinite(r["shown_strain"]) and r["shown_strain"] > 0
    out = rows[0]
    assert out["layer_penetrating"] == 0 and out["tuck_as_asked"] is True  # the top's hem over the band
    assert out["shown_strain"] <= 0.16  # what the page draws is within the cloth's limits (issue 51's 16 %)


def test_self_contact_section_times_a_drape_with_and_without(bench):
    """Quick mode: the T-shirt M on the medium body, its time to rest with the cloth's contact with itself off and
    on, alternated; the ratio is of the two medians, and the drape with it on is as clean as without."""
    _, _, report = bench
    rows = _section(report, "selfcontact")["data"]["rows"]
    assert [r["garment"] for r in rows] == ["T-shirt M"]
    r = rows[0]
    assert r["off_s"] > 0 and r["on_s"] > 0 and r["ratio"] == pytest.approx(r["on_s"] / r["off_s"])
    assert r["off_steps"] > 0 and r["on_steps"] > 0
    assert r["on_crossings"] <= r["off_crossings"]
