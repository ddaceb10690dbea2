"""Issue 2: the app factory, a real `tryon serve` process, the page in a real browser, packaging."""

from __future__ import annotations

import json
import re
from pathlib import Path

import httpx
import pytest
from fastapi.testclient import TestClient

from tryon import __version__
from tryon.api.app import create_app
from tryon.cli import build_parser, main
from tryon.config import Settings

ROOT = Path(__file__).resolve().parents[1]


def test_factory_uses_given_settings(settings: Settings):
    app = create_app(settings)
    assert app.state.settings is settings
    assert settings.data_dir.is_dir()
    with TestClient(app) as client:
        r = client.get("/api/health")
        assert r.status_code == 200
        assert r.json()["status"] == "ok"
        assert r.json()["version"] == __version__


def test_settings_from_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("TRYON_DATA_DIR", str(tmp_path / "d"))
    monkeypatch.setenv("TRYON_ADMIN_TOKEN", "s3cret")
    s = Settings()
    assert s.data_dir == tmp_path / "d"
    assert s.admin_token == "s3cret"
    monkeypatch.delenv("TRYON_ADMIN_TOKEN")
    assert Settings().admin_token is None


def test_page_and_three_served_by_app(settings: Settings):
    with TestClient(create_app(settings)) as client:
        page = client.get("/")
        assert page.status_code == 200
        assert "importmap" in page.text
        three = client.get("/vendor/three/build/three.module.js")
        assert three.status_code == 200
        assert "REVISION" in three.text
        assert client.get("/vendor/three/examples/jsm/controls/OrbitControls.js").status_code == 200


def test_cli_serve_defaults():
    args = build_parser().parse_args(["serve"])
    assert (args.host, args.port) == ("127.0.0.1", 8000)


@pytest.mark.parametrize("port", ["99999", "-1", "http"])
def test_cli_serve_refuses_a_port_out_of_range(port, capsys):
    """99999 used to bind port 34463 (the socket layer takes it modulo 65536)."""
    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args(["serve", "--port", port])
    assert exit_.value.code == 2 and "--port" in capsys.readouterr().err


def test_cli_serve_refuses_an_unusable_data_dir_or_setting(tmp_path, monkeypatch, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("TRYON_DATA_DIR", str(blocker / "data"))
    assert main(["serve", "--port", "0"]) == 2
    assert "cannot write to the data directory" in capsys.readouterr().err
    monkeypatch.setenv("TRYON_DATA_DIR", str(tmp_path / "data"))
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "catalogue.sqlite").write_text("not a database")
    assert main(["serve", "--port", "0"]) == 2
    assert "cannot open the catalogue" in capsys.readouterr().err
    monkeypatch.setenv("TRYON_SIM_WORKERS", "two")
    assert main(["serve", "--port", "0"]) == 2
    assert "TRYON_SIM_WORKERS='two'" in capsys.readouterr().err


M = '{"height": 170, "chest": 100, "waist": 90, "hips": 100}'


@pytest.mark.parametrize("path, text, content_type, status, words", [
    # Python's json reads NaN / Infinity: a 422 naming the field (was a 500: the echoed input was not JSON)
    ("/api/tryon", '{"garment_id": "x", "measurements": %s, "settings": {"time_step": NaN}}' % M,
     "application/json", 422, "finite number"),
    ("/api/tryon", '{"garment_id": "x", "measurements": %s, "settings": {"simplification": 1e400}}' % M,
     "application/json", 422, "finite number"),
    ("/api/bodies", '{"measurements": %s}' % M, "text/plain", 422, "Content-Type: application/json"),
    ("/api/bodies", '{"measurements": ', "application/json", 422, "not valid JSON at offset 17"),
    ("/api/bodies", b"\xff\xfe{", "application/json", 400, "not UTF-8"),
    ("/api/bodies", "[" * 100_000 + "]" * 100_000, "application/json", 400, "nested too deeply"),
    # deep enough for the echo of the bad input to exhaust the stack (was a 500), not for the JSON reader
    ("/api/bodies", '{"measurements": {"height": %s170%s}}' % ("[" * 500, "]" * 500), "application/json", 422,
     "valid number"),
])
def test_unreadable_requests_get_a_reason(settings: Settings, path, text, content_type, status, words):
    with TestClient(create_app(settings)) as client:
        r = client.post(path, content=text, headers={"content-type": content_type})
    assert r.status_code == status, r.text
    assert words in str(r.json()["detail"]), r.json()


def test_validation_errors_echo_bad_input_cut_short(settings: Settings):
    with TestClient(create_app(settings)) as client:
        r = client.post("/api/bodies", json={"measurements": json.loads(M), "pad": "x" * 100_000})
    assert r.status_code == 422
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", "pad"] and len(detail["input"]) < 300 and "100,000 characters" in detail["input"]


@pytest.mark.parametrize("method, path, status, allow, words", [
    ("GET", "/api/tryon", 405, "POST", "use POST"),  # was a bare 404 from the static files
    ("PUT", "/api/garments", 405, "GET, POST", "use GET or POST"),  # was a 405 allowing GET, HEAD
    ("PUT", "/api/garments/abc", 405, "GET, PATCH, DELETE", "use GET or PATCH or DELETE"),
    ("GET", "/api/nope", 404, None, "no API route GET /api/nope"),
    ("GET", "/api/garments/abc", 404, None, "no garment with id 'abc'"),  # a route's own 404 is kept
])
def test_wrong_method_or_path_under_api_is_named(settings: Settings, method, path, status, allow, words):
    with TestClient(create_app(settings)) as client:
        r = client.request(method, path)
    assert r.status_code == status and r.headers.get("allow") == allow
    assert words in r.json()["detail"]


@pytest.mark.e2e
def test_real_server_health_page_and_three(live_server: str):
    health = httpx.get(f"{live_server}/api/health", timeout=5)
    assert health.json()["status"] == "ok"
    page = httpx.get(f"{live_server}/", timeout=5)
    assert page.status_code == 200 and "importmap" in page.text
    imports = dict(re.findall(r'"(three[^"]*)":\s*"([^"]+)"', page.text))
    module = httpx.get(live_server + imports["three"], timeout=5)
    assert module.status_code == 200 and "REVISION" in module.text
    addon = httpx.get(live_server + imports["three/addons/"] + "controls/OrbitControls.js", timeout=5)
    assert addon.status_code == 200


@pytest.mark.e2e
def test_browser_renders_scene_without_errors(live_server: str, browser):
    page = browser.new_page(viewport={"width": 800, "height": 600})
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(live_server + "/")
    page.wait_for_selector("canvas")
    page.wait_for_timeout(500)
    # Read the canvas back: a rendered scene has more than one colour.
    colours = page.evaluate(
        """() => { const c = document.querySelector('canvas');
                   const gl = c.getContext('webgl2') || c.getContext('webgl');
                   const px = new Uint8Array(c.width * c.height * 4);
                   gl.readPixels(0, 0, c.width, c.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
                   const seen = new Set();
                   for (let i = 0; i < px.length; i += 4 * 97) seen.add(px[i] << 16 | px[i+1] << 8 | px[i+2]);
                   return seen.size; }"""
    )
    page.close()
    assert colours > 3, "canvas looks blank"
    assert errors == []


def test_dockerfile_copies_existing_files():
    text = (ROOT / "Dockerfile").read_text().replace("\\\n", " ")  # join continued lines
    assert re.search(r"^HEALTHCHECK .*api/health", text, re.M)
    assert re.search(r"^USER (?!root)", text, re.M)
    assert "EXPOSE 8000" in text
    for line in re.findall(r"^COPY (?:--\S+ )*(.+)$", text, re.M):
        *sources, _dest = line.split()
        for src in sources:
            assert (ROOT / src).exists(), f"Dockerfile copies {src}, which does not exist"


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    assert "bash scripts/test.sh" in readme and "bash scripts/serve.sh" in readme
    assert "scripts/test.sh" in (ROOT / ".ci" / "run").read_text()
