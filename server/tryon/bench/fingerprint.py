"""Fingerprints of drapes, to tell a refactor that changes nothing from one that changes the drapes.

``python3 -m tryon.bench.fingerprint OUT.json [--compare BEFORE.json] [--garments DIR]`` drapes each catalogue
garment of size M on the fit section's medium body, a few other sizes on the small and large bodies and two
poses, and writes per drape a hash of the shown mesh and the simulated positions (bit for bit) beside its
steps, penetrating vertices and springs over. ``--garments DIR`` adds every .obj file of DIR (on the medium
body). With ``--compare`` it exits 1 and lists the drapes that differ.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

from tryon.bench.fit import BODIES
from tryon.bench.scenes import catalogue_entries, garments_dir

# (file, body, pose): the catalogue's M garments on the medium body, too-small and too-large sizes, two poses
CASES = [(f"{kind}-m.obj", "medium", None)
         for kind in ("tshirt", "longsleeve", "dress", "skirt", "trousers", "shorts")]
CASES += [("tshirt-s.obj", "large", None), ("trousers-l.obj", "small", None),
          ("longsleeve-m.obj", "medium", {"arm_angle": 15.0, "elbow_bend": 100.0}),
          ("skirt-l.obj", "large", {"arm_angle": 60.0, "leg_spread": 10.0})]


def fingerprint(extra: Path | None = None, log=print) -> dict:
    """{case: {hash, steps, penetrating, over}} of every drape (see the module doc)."""
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.garment.catalogue import guess_category
    from tryon.garment.ingest import load_garment
    from tryon.garment.prepare import prepare
    from tryon.sim.run import drape

    entries = {e["file"]: e for e in catalogue_entries()}
    cases = [(garments_dir() / f, b, p, entries[f]) for f, b, p in CASES]
    if extra is not None:
        cases += [(path, "medium", None, None) for path in sorted(Path(extra).glob("*.obj"))]
    out, models = {}, {}
    for path, body_name, pose, entry in cases:
        if path not in models:
            mesh = load_garment(path.read_bytes(), path.name, units=(entry or {}).get("units", "auto"))
            category = entry["category"] if entry else guess_category(path.name) or "top"
            models[path] = prepare(mesh, id=path.name, name=path.stem, category=category,
                                   size=(entry or {}).get("size"), source_sha256="-", source_name=path.name)
        body = build_body(Measurements(**BODIES[body_name]), Pose(**(pose or {})))
        t = time.perf_counter()
        result = drape(body, models[path])
        digest = hashlib.sha256(np.ascontiguousarray(result.vertices).tobytes()
                                + np.ascontiguousarray(result.coarse).tobytes()).hexdigest()[:16]
        m = result.metrics
        key = f"{path.name}@{body_name}" + ("+" + ",".join(f"{k}={v:g}" for k, v in pose.items()) if pose else "")
        out[key] = {"hash": digest, "steps": m["steps"], "penetrating": m["penetrating_vertices"],
                    "over": sum(k["over"] for k in m["strain_by_kind"].values())}
        log(f"{key}: {out[key]} ({time.perf_counter() - t:.2f} s)")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python3 -m tryon.bench.fingerprint", description=__doc__.split("\n")[0])
    parser.add_argument("out", type=Path, help="where to write the fingerprints (JSON)")
    parser.add_argument("--compare", type=Path, help="fingerprints from before the change: list what differs")
    parser.add_argument("--garments", type=Path, help="a directory of .obj garments to drape too")
    args = parser.parse_args(argv)
    now = fingerprint(args.garments)
    args.out.write_text(json.dumps(now, indent=1, sort_keys=True))
    if args.compare is None:
        return 0
    before = json.loads(args.compare.read_text())
    changed = sorted(k for k in set(now) | set(before) if now.get(k) != before.get(k))
    for key in changed:
        print(f"differs: {key}: {before.get(key)} -> {now.get(key)}")
    print("identical" if not changed else f"{len(changed)} of {len(now)} drapes differ")
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
