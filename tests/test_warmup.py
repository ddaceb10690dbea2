"""Issue 32: the service is ready when it can serve. The warm-up compiles (or loads) every kernel a request
needs, so the first try-on after ``/api/health`` says ok compiles nothing; until then health says
``"starting"`` (503)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest
from fastapi.testclient import TestClient

from tryon.api.app import create_app
from tryon.api.warmup import warm_up
from tryon.config import Settings

# Run in a fresh interpreter (this one compiled everything long ago): warm up, then serve requests unlike
# the warm-up's (other garments, sizes, body, pose, settings, formats) and list every kernel that gained a
# compiled signature meanwhile.
FIRST_REQUESTS = textwrap.dedent("""
    import json, sys, tempfile
    from pathlib import Path
    from numba.core.registry import CPUDispatcher
    from tryon.api.warmup import warm_up

    def signatures():
        out = {}
        for name, module in list(sys.modules.items()):
            if name.startswith("tryon"):
                for value in vars(module).values():
                    if isinstance(value, CPUDispatcher):
                        out[value.py_func.__module__ + "." + value.__name__] = len(value.signatures)
        return out

    warm_up()
    before = signatures()
    from tryon.api.export import json_bytes, mesh_bytes
    from tryon.api.routes.bodies import body_glb, body_json
    from tryon.api.service import result_json, run_tryon, strain_colours
    from tryon.api.schemas.tryon import TryOnRequest
    from tryon.body.build import build_body
    from tryon.api.schemas.bodies import to_body_params
    from tryon.garment.catalogue import Catalogue
    from tryon.garment.generate import garment_mesh, obj_text

    tmp = Path(tempfile.mkdtemp())
    catalogue = Catalogue(tmp / "data")
    measurements = {"height": 182, "chest": 104, "waist": 90, "hips": 104, "inseam": 84}
    pose = {"arm_angle": 50, "elbow_bend": 30, "leg_spread": 8}
    for kind, size, category in (("skirt", "M", "bottom"), ("dress", "L", "dress"), ("longsleeve", "L", "top"),
                                 ("shorts", "XL", "bottom")):
        path = tmp / f"{kind}.obj"
        path.write_text(obj_text(garment_mesh(kind, size), kind))
        gid = catalogue.ingest(path, name=kind, category=category, size=size, units="m", simplify=0.25).id
        request = TryOnRequest(garment_id=gid, measurements=measurements, pose=pose,
                               settings={"substeps": 8, "max_steps": 120})
        result = run_tryon(catalogue, request)
        result_json(result)
        mesh_bytes(result.vertices, result.faces, "glb", strain_colours(result.strain, 0.1))
        catalogue.model(gid, 0.25).expand(result.coarse)
    top = next(e.id for e in catalogue.list() if e.category == "top")
    bottom = next(e.id for e in catalogue.list() if e.category == "bottom")
    outfit = TryOnRequest(garment_ids=[top, bottom], tuck="in", measurements=measurements, pose=pose,
                          settings={"substeps": 8, "max_steps": 120})
    from tryon.api.service import result_glb
    result_glb(run_tryon(catalogue, outfit))
    request = TryOnRequest(garment_id="-", measurements=measurements, pose=pose)
    body = build_body(*to_body_params(request.measurements, request.pose), 24)
    json_bytes(body_json(body, request.pose.angles()))
    body_glb(body)
    # a live session's re-poses, unlike the warm-up's: another garment, body and poses
    from tryon.api.pool import RunGuard
    from tryon.body.params import Measurements, pose_from
    from tryon.sim.repose import repose, settle
    from tryon.sim.start import start
    d = start(body, catalogue.model(top, 0.25))
    settle(d, RunGuard(60.0))
    for name in ("arms_raised", "stride"):
        d = repose(d, build_body(Measurements(**measurements), pose_from(name), 24))
        settle(d, RunGuard(60.0), give_way=lambda: False)
    after = signatures()
    print(json.dumps({name: after[name] - before.get(name, 0) for name in after if after[name] != before.get(name, 0)}))
""")


@pytest.mark.slow
def test_first_requests_after_warm_up_compile_nothing():
    warm_up()  # this process: the kernels are in the disk cache, so the child only loads them
    out = subprocess.run([sys.executable, "-c", FIRST_REQUESTS], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    compiled = json.loads(out.stdout.strip().splitlines()[-1])
    assert compiled == {}, f"kernels compiled on a first request after the warm-up: {compiled}"


def test_health_says_starting_until_warm(tmp_path):
    app = create_app(Settings(data_dir=tmp_path / "data"))
    with TestClient(app) as client:
        assert client.get("/api/health").json()["status"] == "ok"  # this process is warm: ready at once
        app.state.warmup.state = "starting"  # as it is while a fresh process warms up
        r = client.get("/api/health")
        assert r.status_code == 503
        assert r.json()["status"] == "starting"
        assert r.json()["warmup"]["state"] == "starting"
        app.state.warmup.state = "ready"
        r = client.get("/api/health")
        assert r.status_code == 200 and r.json()["status"] == "ok"


def test_warm_up_runs_once_per_process():
    warm_up()
    assert warm_up() == 0.0
