"""Issue 30 on the page: the pose controls (a named pose, each side's sliders) and, once a garment is on,
live re-posing over the same connection; in headless Chromium against a real ``tryon serve``.

Before a try-on a named pose re-builds the body; after one the pose controls act live: choosing a pose or
moving a slider sends a pose update, the body moves with the garment on it, and the fit summary is that of
the new pose. The layout stays within the screen at 1366 x 768 and 390 x 844. Screenshots:
``test-artifacts/page-pose-<w>x<h>.png`` (the pose controls) and ``page-pose-<w>x<h>-live.png`` (re-posed).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from test_page_layout import LAYOUT_PROBLEMS, open_page
from tryon.body.params import NAMED_POSES

pytestmark = [pytest.mark.e2e, pytest.mark.slow]  # the fast lane keeps test_page.py

ROOT = Path(__file__).resolve().parents[1]
ARTIFACTS = ROOT / "test-artifacts"
DONE = "window.tryon.state === 'done' || window.tryon.state === 'error'"


@pytest.fixture(scope="module")
def pose_shop(shared_server) -> str:
    with shared_server.stocked("test_page_pose") as stock:
        stock.add(ROOT / "garments" / "tshirt-m.obj", name="T-shirt M", category="top", size="M", units="m")
        yield shared_server.url


@pytest.mark.parametrize(("width", "height"), [(1366, 768), (390, 844)], ids=["1366x768", "390x844"])
def test_named_poses_side_sliders_and_live_reposing(browser, pose_shop, width, height):
    context, page = open_page(browser, pose_shop, width, height)
    try:
        options = page.locator("#pose-name option")
        assert options.evaluate_all("os => os.map((o) => o.value)") == [*NAMED_POSES, ""]
        assert page.locator("#pose .pose-grid input[type=range]").count() == 12  # six joints, two sides
        # a named pose before a try-on: a new body in that pose
        before = page.evaluate("window.tryon.bodyRequests")
        page.select_option("#pose-name", "hands_on_hips")
        page.wait_for_function(f"window.tryon.bodyRequests > {before}", timeout=30_000)
        assert page.input_value("#pose-elbow_bend_left") == "100"
        assert page.evaluate("window.tryon.stage.body.geometry.attributes.position.count") > 5000
        # one side's slider alone ("both sides alike" off): the request gives the side angles
        page.uncheck("#pose-link")
        page.fill("#pose-arm_angle_right", "60")
        page.dispatch_event("#pose-arm_angle_right", "input")
        assert page.input_value("#pose-arm_angle_left") != "60"
        assert page.input_value("#pose-name") == ""
        ARTIFACTS.mkdir(exist_ok=True)
        page.evaluate("document.querySelector('#pose').scrollIntoView({block: 'center'})")
        page.mouse.move(width / 2, 10)
        page.wait_for_timeout(400)
        page.screenshot(path=str(ARTIFACTS / f"page-pose-{width}x{height}.png"))
        assert page.evaluate(LAYOUT_PROBLEMS) == []

        # try it on; then the pose controls act live over the open connection
        page.select_option("#pose-name", "a_pose")
        page.click("#tryon-button")
        page.wait_for_function(DONE, timeout=120_000)
        assert page.evaluate("window.tryon.state") == "done", page.evaluate("window.tryon.lastError")
        assert page.evaluate("window.tryon.live && window.tryon.live.open")
        requests = page.evaluate("window.tryon.bodyRequests")
        page.select_option("#pose-name", "arms_raised")
        page.wait_for_function("window.tryon.poseDones >= 1", timeout=60_000)
        assert page.evaluate("window.tryon.done.metrics.pose.elbow_bend_left") == 90
        assert page.evaluate("window.tryon.done.metrics.penetrating_vertices") == 0
        assert page.evaluate("window.tryon.bodyRequests") == requests  # no separate body: it came with the garment
        # the body on the stage is the re-posed one: its forearms up, the hands out at the sides as high as the
        # head (in the A-pose they hang below the hips)
        top = page.evaluate("""() => { const p = window.tryon.stage.body.geometry.attributes.position.array;
            let m = -1e9; for (let i = 0; i < p.length; i += 3) if (Math.abs(p[i]) > 0.4) m = Math.max(m, p[i + 1]);
            return m; }""")
        assert top > 1.6
        page.mouse.move(width / 2, 10)
        page.wait_for_timeout(400)
        page.screenshot(path=str(ARTIFACTS / f"page-pose-{width}x{height}-live.png"))
        assert page.evaluate(LAYOUT_PROBLEMS) == []
        # "Motion .glb": the garment moving through the poses it settled in (the A-pose, then arms raised)
        assert page.evaluate("window.tryon.motionPoses.length") == 2
        with page.expect_download(timeout=120_000) as download:
            page.click("#download-motion")
        assert download.value.suggested_filename == "t-shirt-m-motion.glb"
        glb = Path(download.value.path()).read_bytes()
        assert glb[:4] == b"glTF"
        gltf = json.loads(glb[20:20 + int.from_bytes(glb[12:16], "little")])
        assert len(gltf["animations"]) >= 1
        assert page.problems == []
    finally:
        context.close()
