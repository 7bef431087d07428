"""What loading a robot file costs, and what the gravity check adds to it.

    .venv/bin/python benchmarks/bench_load.py [--repeat R]

For each robot in ``robots/`` and each URDF of the test corpus (``tests/urdfs/``, with the robot
file ``akarm init`` writes for it), best of R runs (other processes only ever make a run slower):

- ``load``: :func:`akarm.load_robot`, the gravity check computed afresh;
- ``cached``: the same with the gravity result kept from an earlier load of the same robot (what
  the test suite and long-lived programs mostly see);
- ``gravity``: :func:`akarm.dynamics.gravity.gravity_peaks` alone, and the gravity evaluations it makes;
- ``init``: :func:`akarm.robotfile.starter.suggest` (``akarm init``) for the corpus URDFs.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from akarm import load_robot  # noqa: E402
from akarm.dynamics import gravity  # noqa: E402
from akarm.dynamics.model import RobotModel  # noqa: E402
from akarm.robotfile.starter import suggest  # noqa: E402


def best(fn, repeat: int) -> float:
    out = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t0)
    return out


def evaluations(config) -> int:
    model = RobotModel(config)
    count = [0]

    def g(q):
        count[0] += 1
        return model.gravity(q)

    gravity.peak_abs(g, [j.limits.lower for j in config.joints], [j.limits.upper for j in config.joints])
    return count[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        files = sorted((ROOT / "robots").glob("*.yaml"))
        init_ms = {}
        for urdf in sorted((ROOT / "tests" / "urdfs").glob("*.urdf")):
            out = Path(tmp) / f"{urdf.stem}.yaml"
            init_ms[urdf.stem] = best(lambda urdf=urdf, out=out: suggest(urdf, out), max(3, args.repeat // 4)) * 1e3
            text = suggest(urdf, out).text.replace(f"urdf: {urdf.name}", f"urdf: {urdf}")
            out.write_text(text)
            files.append(out)
        print(f"ms, best of {args.repeat}")
        print(f"{'robot':>14} {'joints':>6} {'load':>7} {'cached':>7} {'gravity':>8} {'evals':>6} {'init':>7}")
        for path in files:
            config = load_robot(path)

            def cold(path=path):
                gravity.clear_cache()
                load_robot(path)

            def alone(config=config):
                gravity.clear_cache()
                gravity.gravity_peaks(config)

            row = [best(cold, args.repeat), best(lambda path=path: load_robot(path), args.repeat),
                   best(alone, args.repeat)]
            init = init_ms.get(path.stem)
            print(f"{path.stem:>14} {len(config.joints):>6} " + " ".join(f"{x * 1e3:7.2f}" for x in row) +
                  f" {evaluations(config):>7}" + (f" {init:7.1f}" if init is not None else ""))


if __name__ == "__main__":
    main()
