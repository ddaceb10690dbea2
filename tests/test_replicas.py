"""Issue 31: two ``tryon serve`` replicas on one machine share one catalogue (the same TRYON_DATA_DIR): an
ingestion through one is seen by the other without a restart, and ingestions through both at once leave a
sound catalogue (every entry once, every model loadable, the same file one entry)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest

from conftest import ADMIN_TOKEN, serve_process
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import garment_mesh, obj_text

pytestmark = [pytest.mark.e2e, pytest.mark.slow]
AUTH = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
MEASUREMENTS = {"height": 170, "chest": 92, "waist": 76, "hips": 98}


def upload(url: str, name: str, data: bytes, category: str) -> httpx.Response:
    return httpx.post(f"{url}/api/garments", headers=AUTH, timeout=120,
                      files={"file": (f"{name}.obj", data)}, data={"name": name, "category": category, "units": "m"})


def names(url: str) -> list[str]:
    return sorted(g["name"] for g in httpx.get(f"{url}/api/garments", timeout=10).json()["garments"])


def test_two_replicas_share_one_catalogue(shared_server):
    """Replica A is the session's shared server (its catalogue emptied for this test), B a second process on
    the same data directory."""
    data = shared_server.data_dir
    files = {kind: obj_text(garment_mesh(kind, size), kind).encode()
             for kind, size in (("skirt", "S"), ("shorts", "S"), ("tshirt", "S"), ("trousers", "S"))}
    with shared_server.stocked("test_replicas"), serve_process(data) as b:
        a = shared_server.url
        # one ingestion through A, seen by B at once, and B drapes it
        r = upload(a, "skirt", files["skirt"], "bottom")
        assert r.status_code == 201, r.text
        assert names(b) == ["skirt"]
        gid = r.json()["id"]
        tryon = httpx.post(f"{b}/api/tryon", json={"garment_id": gid, "measurements": MEASUREMENTS}, timeout=120)
        assert tryon.status_code == 200 and tryon.json()["metrics"]["rest_reached"]

        # ingestions through both at once: two other files, and the same file through both
        jobs = [(a, "shorts", files["shorts"], "bottom"), (b, "tshirt", files["tshirt"], "top"),
                (a, "trousers", files["trousers"], "bottom"), (b, "trousers", files["trousers"], "bottom")]
        with ThreadPoolExecutor(len(jobs)) as pool:
            answers = list(pool.map(lambda job: upload(*job), jobs))
        assert all(r.status_code in (200, 201) for r in answers), [r.text for r in answers]
        assert answers[2].json()["id"] == answers[3].json()["id"]  # the same file is one entry
        assert names(a) == names(b) == ["shorts", "skirt", "trousers", "tshirt"]

        # a deletion through B is seen by A
        assert httpx.delete(f"{b}/api/garments/{gid}", headers=AUTH, timeout=10).status_code == 204
        assert httpx.get(f"{a}/api/garments/{gid}", timeout=10).status_code == 404
        assert names(a) == ["shorts", "trousers", "tshirt"]

        # the catalogue on disk is sound: every entry's model loads
        catalogue = Catalogue(data)
        assert sorted(meta.name for meta in catalogue.list()) == ["shorts", "trousers", "tshirt"]
        for meta in catalogue.list():
            assert len(catalogue.model(meta.id).springs) > 0
