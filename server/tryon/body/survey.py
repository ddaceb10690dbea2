"""Build the body of every person in an ANSUR II style CSV (millimetres) and report the measurement errors.

    python3 -m tryon.body.survey ansur2_sample.csv [--all-measurements] [--resolution N]

Columns used: stature, chestcircumference, waistcircumference, buttockcircumference (required), and with
``--all-measurements`` also biacromialbreadth, acromionradialelength + radialestylionlength (arm length),
crotchheight (inseam), neckcircumference, thighcircumference, bicepscircumferenceflexed (upper arm).
Prints the largest and mean |achieved - requested| (cm) per measurement, the same for a hip tape that
also goes round the thighs (they must stay inside the torso's hip section), and the build time.
"""

from __future__ import annotations

import argparse
import csv
import time

import numpy as np

from tryon.body.build import DEFAULT_RESOLUTION, build_body
from tryon.body.measure import horizontal_girth, mesh_edges
from tryon.body.params import Measurements, Pose, check_measurements
from tryon.body.types import PART_NAMES


# Required columns of an ANSUR II style CSV (millimetres) and the measurement each gives.
REQUIRED_COLUMNS = {"stature": "height", "chestcircumference": "chest", "waistcircumference": "waist",
                    "buttockcircumference": "hips"}


def ansur_measurements(row: dict, all_measurements: bool = False) -> dict[str, float]:
    """The measurements (cm) of one CSV row (mm): height, chest, waist, hips, and with ``all_measurements``
    the optional ones too. KeyError for a missing column, ValueError for a value that is not a number."""
    cm = {k: float(v) / 10.0 for k, v in row.items() if k in REQUIRED_COLUMNS or all_measurements
          and k not in ("subjectid", "Gender")}
    kw = {name: cm[column] for column, name in REQUIRED_COLUMNS.items()}
    if all_measurements:
        kw.update(shoulder_width=cm["biacromialbreadth"],
                  arm_length=cm["acromionradialelength"] + cm["radialestylionlength"],
                  inseam=cm["crotchheight"], neck=cm["neckcircumference"],
                  thigh=cm["thighcircumference"], upper_arm=cm["bicepscircumferenceflexed"])
    return kw


def read_people(path: str, all_measurements: bool) -> list[Measurements]:
    """Measurements (cm) of every row of the CSV (mm)."""
    with open(path, newline="", encoding="latin-1") as fh:
        return [Measurements(**ansur_measurements(row, all_measurements)) for row in csv.DictReader(fh)]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("--all-measurements", action="store_true")
    ap.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION)
    ap.add_argument("--pose", nargs=3, type=float, metavar=("ARM", "ELBOW", "LEGS"))
    args = ap.parse_args(argv)
    pose = Pose(*args.pose) if args.pose else Pose()
    people = read_people(args.csv, args.all_measurements)
    errors: dict[str, list[float]] = {}
    refused = 0
    times = []
    for m in people:
        if check_measurements(m):
            refused += 1
            print("refused:", check_measurements(m))
            continue
        t0 = time.perf_counter()
        body = build_body(m, pose, args.resolution)
        times.append(time.perf_counter() - t0)
        for name, value in body.requested.items():
            errors.setdefault(name, []).append(abs(body.achieved[name] - value))
        # a tape at hip level goes round the thighs too: they must stay inside the torso's section there
        with_thighs = np.isin(body.face_part, [PART_NAMES.index(p) for p in ("torso", "thigh_l", "thigh_r")])
        edges = mesh_edges(body.faces[with_thighs])
        tape = horizontal_girth(body.vertices, edges, body.levels["hips"]) * 100.0
        errors.setdefault("hips incl. thighs", []).append(abs(tape - body.requested["hips"]))
    print(f"{len(people)} people, {refused} refused, resolution {args.resolution}, pose {pose}, "
          f"{len(body.vertices)} vertices")
    for name, errs in errors.items():
        e = np.array(errs)
        print(f"  {name:15s} max |error| {e.max():8.4f} cm   mean {e.mean():8.4f} cm")
    t = np.array(times[1:]) * 1e3
    print(f"  build (after the first): median {np.median(t):.2f} ms, max {t.max():.2f} ms")


if __name__ == "__main__":
    main()
