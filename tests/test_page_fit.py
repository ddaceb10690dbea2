"""Issue 27 on the page: "Which size fits me?" in headless Chromium against a real ``tryon serve`` process.

The catalogue: the T-shirt in five sizes as a style with its chart rows, and a skirt without a style. Choose
the T-shirt, enter the measurements of the chart's M row's centre, press "Find my size": every size's verdict,
ease and reason, M recommended (its row and its chip marked) and its drape shown, answered from the result
cache the advice filled; one click on another size's row shows that size's drape, from the cache too. The
layout stays within the screen at 1366 x 768 and 390 x 844 (``test_page_layout.LAYOUT_PROBLEMS``); the skirt
comes in no sizes of a style, so the button is off for it. Screenshots: ``test-artifacts/page-fit-<w>x<h>.png``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from test_page_layout import LAYOUT_PROBLEMS, open_page
from tryon.garment.generate import chart_row, garment_mesh, obj_text

pytestmark = [pytest.mark.e2e, pytest.mark.slow]  # the fast lane keeps test_page.py

ROOT = Path(__file__).resolve().parents[1]
ARTIFACTS = ROOT / "test-artifacts"
AT_M = {"height": "170", "chest": "96", "waist": "82", "hips": "100"}


@pytest.fixture(scope="module")
def fit_shop(shared_server) -> str:
    with shared_server.stocked("test_page_fit") as stock:
        for size in ("S", "M", "L", "XL", "XXL"):
            stock.add(obj_text(garment_mesh("tshirt", size), f"T-shirt {size}"), f"tshirt-{size}.obj",
                      name=f"T-shirt {size}", category="top", size=size, units="m", style="tshirt",
                      chart=chart_row(size, "top"))
        stock.add(obj_text(garment_mesh("skirt", "M"), "A-line skirt M"), "skirt-m.obj", name="A-line skirt M",
                  category="bottom", size="M", units="m")
        yield shared_server.url


ADVICE = """() => [...document.querySelectorAll('#size-advice li')].map((li) => ({
    size: li.querySelector('.advice-size').textContent, verdict: li.querySelector('.advice-verdict').textContent,
    ease: li.querySelector('.advice-ease')?.textContent ?? '', reason: li.querySelector('.advice-reason').textContent,
    recommended: li.classList.contains('recommended'), id: li.querySelector('.advice-row').dataset.id,
    current: li.querySelector('.advice-row').getAttribute('aria-current') === 'true'}))"""
DONE = "window.tryon.state === 'done' || window.tryon.state === 'error'"


@pytest.mark.parametrize(("width", "height"), [(1366, 768), (390, 844)], ids=["1366x768", "390x844"])
def test_find_my_size(browser, fit_shop, width, height):
    context, page = open_page(browser, fit_shop, width, height)
    try:
        assert page.locator("#garments .garment").count() == 2  # the T-shirt's row and the skirt's
        page.get_by_role("radio", name="A-line skirt, size M", exact=True).click()
        assert page.locator("#fit-button").is_disabled()
        assert "several sizes" in page.text_content("#fit-note")
        page.get_by_role("radio", name="T-shirt, size S", exact=True).click()
        assert page.locator("#fit-button").is_enabled()
        assert "S, M, L, XL, XXL" in page.text_content("#fit-note")
        for name, value in AT_M.items():
            page.fill(f"#field-{name}", value)
        page.wait_for_function("window.tryon.bodyRequests > 1")

        page.click("#fit-button")
        page.wait_for_function(f"window.tryon.advice && window.tryon.garmentId && ({DONE})", timeout=120_000)
        assert page.evaluate("window.tryon.state") == "done", page.evaluate("window.tryon.lastError")
        rows = page.evaluate(ADVICE)
        assert [r["size"] for r in rows] == ["S", "M", "L", "XL", "XXL"]
        assert [r["verdict"] for r in rows] == ["Fits", "Fits", "Fits", "Not draped", "Not draped"]
        assert [r["recommended"] for r in rows] == [False, True, False, False, False]
        assert rows[1]["ease"].startswith("ease +") and rows[1]["ease"].endswith(" cm chest")
        assert rows[1]["reason"].endswith("stays on the shoulders")
        assert page.text_content("#fit-summary").startswith("Take M: the chart's size for you is M; M fits")
        # the recommended size is shown, from the cache the advice filled; its chip is chosen and marked
        assert page.evaluate("window.tryon.garmentId") == rows[1]["id"] and rows[1]["current"]
        assert page.evaluate("window.tryon.done.cached") is True
        chip = page.get_by_role("radio", name="T-shirt, size M", exact=True)
        assert chip.get_attribute("aria-checked") == "true" and "recommended" in chip.get_attribute("class")

        # one click shows another size's drape (a cached one again)
        page.locator("#size-advice .advice-row").nth(2).click()
        page.wait_for_function(f"window.tryon.garmentId === '{rows[2]['id']}' && ({DONE})", timeout=60_000)
        page.wait_for_function(DONE, timeout=60_000)
        assert page.evaluate("window.tryon.state") == "done"
        assert page.evaluate("window.tryon.done.cached") is True
        assert [r["current"] for r in page.evaluate(ADVICE)] == [False, False, True, False, False]

        # a slim fit: the advice again, from the drapes already made; S is marked
        page.select_option("#fit-preference", "slim")
        page.wait_for_function("window.tryon.advice && window.tryon.advice.preference === 'slim'", timeout=60_000)
        assert [r["recommended"] for r in page.evaluate(ADVICE)] == [True, False, False, False, False]
        assert page.text_content("#fit-summary").startswith("Take S: the chart's size for you is M, S for a slim fit")
        page.select_option("#fit-preference", "regular")
        page.wait_for_function("window.tryon.advice && window.tryon.advice.preference === 'regular'", timeout=60_000)
        page.wait_for_function(f"window.tryon.garmentId === '{rows[1]['id']}' && ({DONE})", timeout=60_000)
        # changed twice at once: the second change's advice (asked once the first's is in) and its size (shown
        # once the first's drape, if still on its way, ends)
        page.select_option("#fit-preference", "slim")
        page.select_option("#fit-preference", "regular")
        page.wait_for_function("window.tryon.advice && window.tryon.advice.preference === 'regular' "
                               f"&& !window.tryon.fitting && window.tryon.garmentId === '{rows[1]['id']}' "
                               f"&& ({DONE}) && !window.tryon.showNext", timeout=60_000)
        assert [r["recommended"] for r in page.evaluate(ADVICE)] == [False, True, False, False, False]

        assert page.evaluate(LAYOUT_PROBLEMS) == []
        page.evaluate("document.querySelector('#fit-card').scrollIntoView({block: 'start'})")
        page.mouse.move(width / 2, 10)
        page.wait_for_timeout(300)
        ARTIFACTS.mkdir(exist_ok=True)
        page.screenshot(path=str(ARTIFACTS / f"page-fit-{width}x{height}.png"))

        # new measurements: the advice was for the old ones
        page.fill("#field-chest", "104")
        page.wait_for_function("!window.tryon.advice")
        assert page.evaluate(ADVICE) == [] and page.text_content("#fit-summary") == ""
        assert page.problems == []
    finally:
        context.close()
