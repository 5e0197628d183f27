"""Wall time of ``suds diagnose`` on a 60-cycle swimmer9 recording (not a timed test).

Usage: PYTHONPATH=. .venv/bin/python benchmarks/bench_diagnose.py [BAG.mcap]
Default: the public ``swimmer9_real_rest_offset.mcap``; if it is absent, a 60-cycle swimmer9
recording with a rest offset is simulated first (seeded) and timed the same way.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path


def main() -> int:
    from suds_ros.core.diagnosis import diagnose
    from suds_ros.core.systems import swimmer9_model

    default = Path(__file__).resolve().parents[2] / "shared" / "bags" / "swimmer9_real_rest_offset.mcap"
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else default
    if path.exists():
        from suds_ros.io.bags import read_recording

        rec = read_recording(path)
        label = path.name
    else:
        from suds_ros.core.effects import apply_effects
        from suds_ros.core.rft import RFTChain
        from suds_ros.core.sim import SimConfig, simulate

        model, _ = apply_effects(swimmer9_model(), [{"name": "spring_rest_offset", "joint": "joint_6", "offset": 0.25}])
        rec = simulate(RFTChain(model), SimConfig(cycles=60, seed=4))
        label = "simulated swimmer9 rest offset, 60 cycles"
    t0 = time.perf_counter()
    rep = diagnose(rec, swimmer9_model())
    wall = time.perf_counter() - t0
    stages = ", ".join(f"{k} {v:.1f}s" for k, v in rep.timings.items())
    print(f"diagnose {label}: {rec.n_samples} samples, wall {wall:.1f} s (cumulative: {stages})")
    print(f"  effects: {[(e.name, e.target, dict(e.parameters)) for e in rep.effects]}")
    print(f"  improvement {rep.improvement:.3f}; target < 60 s on 2 cores: {'OK' if wall < 60 else 'SLOW'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
