"""``python3 -m tryon.bench.fingerprint``: the same code drapes the same bits, and a changed drape is named."""

from __future__ import annotations

import json

from tryon.bench import fingerprint


def test_fingerprints_repeat_bit_for_bit_and_a_difference_is_reported(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(fingerprint, "CASES", [("shorts-m.obj", "medium", None),
                                               ("skirt-m.obj", "small", {"arm_angle": 60.0})])
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    assert fingerprint.main([str(first)]) == 0
    assert fingerprint.main([str(second), "--compare", str(first)]) == 0
    assert "identical" in capsys.readouterr().out
    prints = json.loads(first.read_text())
    assert sorted(prints) == ["shorts-m.obj@medium", "skirt-m.obj@small+arm_angle=60"]
    assert all(len(p["hash"]) == 16 and p["steps"] > 0 for p in prints.values())
    prints["shorts-m.obj@medium"]["hash"] = "0" * 16  # as if the code had changed that drape
    first.write_text(json.dumps(prints))
    assert fingerprint.main([str(second), "--compare", str(first)]) == 1
    out = capsys.readouterr().out
    assert "differs: shorts-m.obj@medium" in out and "1 of 2 drapes differ" in out
