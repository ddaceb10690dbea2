"""Issue 29 on the page: a top and a bottom tried on together, in headless Chromium against a real ``tryon serve``.

The catalogue: a T-shirt M and trousers M. Choose the T-shirt, "Wear with" the trousers, the hem over the
waistband, Try on: the stream shows both garments as one outfit; the fit summary names both, says whether cloth
went through cloth and how the hem sits, and gives each garment its own figures. The layout stays within the
screen at 1366 x 768 and 390 x 844. Screenshots: ``test-artifacts/page-outfit-<w>x<h>.png``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import trimesh

from test_page_layout import LAYOUT_PROBLEMS, open_page
from tryon.garment.generate import garment_mesh, obj_text

pytestmark = [pytest.mark.e2e, pytest.mark.slow]  # the fast lane keeps test_page.py

ROOT = Path(__file__).resolve().parents[1]
ARTIFACTS = ROOT / "test-artifacts"
DONE = "window.tryon.state === 'done' || window.tryon.state === 'error'"
FIGURES = """() => [...document.querySelectorAll('#metrics > div')].map((d) => ({
    name: d.querySelector('dt').textContent, value: d.querySelector('dd').textContent,
    head: d.classList.contains('garment-head')}))"""


@pytest.fixture(scope="module")
def outfit_shop(shared_server) -> str:
    with shared_server.stocked("test_page_outfit") as stock:
        for kind, name, category in (("tshirt", "T-shirt M", "top"), ("trousers", "Trousers M", "bottom")):
            stock.add(obj_text(garment_mesh(kind, "M"), name), f"{kind}-m.obj", name=name, category=category,
                      size="M", units="m")
        # a shirt in centimetres whose units are guessed (as a user's upload is): its "Size" row takes the full
        # width
        shirt_cm = garment_mesh("tshirt", "L")
        shirt_cm.apply_scale(100.0)
        stock.add(obj_text(shirt_cm, "Shirt in cm"), "shirt-cm.obj", name="Shirt in cm", category="top",
                  units="auto")
        # a file that is already an outfit (a shirt and trousers in one, as MakeHuman's): worn alone
        both = trimesh.util.concatenate([garment_mesh("tshirt", "L"), garment_mesh("trousers", "L")])
        stock.add(both.export(file_type="obj"), "shirt-and-trousers.obj", name="Shirt and trousers", category="top",
                  units="m")
        yield shared_server.url


@pytest.mark.parametrize(("width", "height"), [(1366, 768), (390, 844)], ids=["1366x768", "390x844"])
def test_a_top_and_a_bottom_worn_together(browser, outfit_shop, width, height):
    context, page = open_page(browser, outfit_shop, width, height)
    try:
        page.get_by_role("radio", name="T-shirt, size M", exact=True).click()
        assert page.is_visible("#companion") and not page.is_visible("#tuck")
        assert page.locator("#companion option").all_text_contents() == ["nothing else", "Trousers M"]
        page.select_option("#companion", label="Trousers M")
        assert page.is_visible("#tuck")
        page.select_option("#tuck", "out")
        page.click("#tryon-button")
        page.wait_for_function(DONE, timeout=120_000)
        assert page.evaluate("window.tryon.state") == "done", page.evaluate("window.tryon.lastError")
        assert [g["name"] for g in page.evaluate("window.tryon.init.garments")] == ["Trousers M", "T-shirt M"]
        assert page.text_content("#result-garment") == "T-shirt M over Trousers M · hem over the waistband"
        figures = page.evaluate(FIGURES)
        assert figures[0] == {"name": "Cloth through cloth", "value": "none", "head": False}
        assert figures[1] == {"name": "Top's hem", "value": "over the waistband", "head": False}
        heads = [f["name"] for f in figures if f["head"]]
        assert heads == ["Trousers M", "T-shirt M"]  # each garment's own figures under its name
        assert sum(f["name"] == "Cloth in body" for f in figures) == 2
        # both garments are on the stage, as one mesh of all their vertices
        assert page.evaluate("window.tryon.stage.garment.geometry.attributes.position.count") == \
            page.evaluate("window.tryon.init.vertex_count")

        # back to one garment: the request is a single garment's again
        page.select_option("#companion", "")
        assert not page.is_visible("#tuck")
        assert page.evaluate(LAYOUT_PROBLEMS) == []
        page.select_option("#companion", label="Trousers M")
        page.mouse.move(width / 2, 10)
        page.wait_for_timeout(300)
        ARTIFACTS.mkdir(exist_ok=True)
        page.screenshot(path=str(ARTIFACTS / f"page-outfit-{width}x{height}.png"))
        assert not page.is_visible("#download-motion")  # a motion is of one garment
        # an outfit does not follow a pose live: a new pose takes it off, and the page says so
        requests = page.evaluate("window.tryon.bodyRequests")
        page.select_option("#pose-name", "arms_raised")
        page.wait_for_function(f"window.tryon.bodyRequests > {requests}", timeout=30_000)
        assert page.is_visible("#notice") and "press “Try on” to see it on this one" in page.inner_text("#notice-text")
        assert page.evaluate("window.tryon.state") == "ready"
        assert page.problems == []
    finally:
        context.close()


# Figures shown above their garment's name or below the next garment's (a two-column grid that packs its cells
# may move one): a list of problems in words.
FIGURES_UNDER_THEIR_NAMES = """() => {
  const items = [...document.querySelectorAll('#metrics > div')];
  const problems = [];
  let head = null;
  items.forEach((d, i) => {
    if (d.classList.contains('garment-head')) { head = d; return; }
    const top = d.getBoundingClientRect().top;
    const name = d.querySelector('dt').textContent;
    if (head && top < head.getBoundingClientRect().bottom) problems.push(`${name} of ${head.textContent} above its name`);
    const next = items.slice(i + 1).find((e) => e.classList.contains('garment-head'));
    if (next && top >= next.getBoundingClientRect().top) problems.push(`${name} below ${next.textContent}`);
  });
  return problems;
}"""


def test_each_garments_figures_stay_under_its_name(browser, outfit_shop):
    """A top of guessed units (its "Size" row full-width, so its section has an odd number of half-width figures)
    tucked into trousers: the trousers' first figure once filled the top's last hole, among the top's figures."""
    context, page = open_page(browser, outfit_shop, 1366, 768)
    try:
        page.get_by_role("radio", name="Shirt in cm", exact=False).click()
        page.select_option("#companion", label="Trousers M")
        page.select_option("#tuck", "in")  # the shirt innermost: its figures first
        page.click("#tryon-button")
        page.wait_for_function(DONE, timeout=120_000)
        assert page.evaluate("window.tryon.state") == "done", page.evaluate("window.tryon.lastError")
        figures = page.evaluate(FIGURES)
        assert [f["name"] for f in figures if f["head"]] == ["Shirt in cm", "Trousers M"]
        assert any(f["name"] == "Size" and "units unknown" in f["value"] for f in figures), figures
        assert page.evaluate(FIGURES_UNDER_THEIR_NAMES) == []
        assert page.problems == []
    finally:
        context.close()


def test_a_file_that_is_already_an_outfit_is_worn_alone(browser, outfit_shop):
    """A shirt-and-trousers file (``pieces`` in the catalogue) offers nothing to wear with it, and is not offered
    as a top to wear with the trousers: either would be refused (422) by the service."""
    context, page = open_page(browser, outfit_shop, 1366, 768)
    try:
        page.get_by_role("radio", name="Shirt and trousers, size one size", exact=True).click()
        assert not page.is_visible("#outfit") and not page.is_visible("#tuck")
        page.get_by_role("radio", name="Trousers, size M", exact=True).click()
        assert page.is_visible("#outfit")
        assert page.locator("#companion option").all_text_contents() == ["nothing else", "T-shirt M", "Shirt in cm"]
        assert page.problems == []
    finally:
        context.close()


def test_a_file_that_is_already_an_outfit_is_tried_on_once_and_says_so(browser, outfit_shop):
    """Issue 50: a shirt-and-trousers file could not be tried on in the page ("live re-posing is not available for a
    garment file of several pieces"): the page asks for it without ``live`` (it drapes once, its pieces as layers),
    says so under the fit summary, and offers no motion; a new pose takes it off, as an outfit's."""
    context, page = open_page(browser, outfit_shop, 1366, 768)
    try:
        page.get_by_role("radio", name="Shirt and trousers, size one size", exact=True).click()
        page.click("#tryon-button")
        page.wait_for_function(DONE, timeout=120_000)
        assert page.evaluate("window.tryon.state") == "done", page.evaluate("window.tryon.lastError")
        assert page.evaluate("window.tryon.live") is None  # no live session was asked for
        assert page.evaluate("window.tryon.init.garment.name") == "Shirt and trousers"
        assert page.evaluate("window.tryon.stage.garment.geometry.attributes.position.count") == \
            page.evaluate("window.tryon.init.vertex_count")
        assert page.is_visible("#result-note") and "Several garments in one file: draped once" in \
            page.inner_text("#result-note")
        assert not page.is_visible("#download-motion")  # a motion is of one garment, moved live
        requests = page.evaluate("window.tryon.bodyRequests")
        page.select_option("#pose-name", "arms_raised")
        page.wait_for_function(f"window.tryon.bodyRequests > {requests}", timeout=30_000)
        assert "press “Try on” to see it on this one" in page.inner_text("#notice-text")
        # a single garment stays live, and its summary has no such note
        page.get_by_role("radio", name="T-shirt, size M", exact=True).click()
        page.click("#tryon-button")
        page.wait_for_function(DONE, timeout=120_000)
        assert page.evaluate("window.tryon.state") == "done", page.evaluate("window.tryon.lastError")
        assert page.evaluate("window.tryon.live !== null") and not page.is_visible("#result-note")
        assert page.problems == []
    finally:
        context.close()
