"""The detection-limit benchmark's quick mode runs and finds a limit on a tiny grid."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[3] / "benchmarks" / "detection_limit.py"


def _load():  # type: ignore[no-untyped-def]
    sys.path.insert(0, str(BENCH.parent))
    spec = importlib.util.spec_from_file_location("detection_limit_bench", BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_quick_mode_runs(capsys) -> None:  # type: ignore[no-untyped-def]
    mod = _load()
    assert mod.main(["--quick"]) == 0
    out = capsys.readouterr().out
    assert "| purcell3 | `spring_rest_offset` joint_2 |" in out


def test_a_large_offset_passes_and_the_reference_is_interpolated() -> None:
    mod = _load()
    (system, name, rungs), = mod.run(["purcell3"], ["spring_rest_offset"], 2, 8, 1e9,
                                     {"spring_rest_offset": [0.1]})[0]
    assert (system, name) == ("purcell3", "spring_rest_offset")
    (r,) = rungs
    assert r.passed and r.named == 2 and r.evidence > 60.0
    assert mod.limit(rungs) == "0.1" and mod.limit(rungs, [0.1, 0.3]) == "≤ 0.1"
    assert mod.reference([mod.Rung(0.01, 0, 2, 10.0), mod.Rung(0.1, 2, 2, 1000.0)], 100.0) == "0.0316"
