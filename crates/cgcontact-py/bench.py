"""1 M points from Python against the Rust library, query only, in the same run.

    CGCONTACT_BIN=target/release/cgcontact python crates/cgcontact-py/bench.py [--points N] [--repeat R]

The Rust side is `cgcontact locate --repeat R --json`: the library's `locate_all_into` on warm
caches into a reused buffer, the fastest of R. The Python side is `Locator.locate` on the same
points (a C-contiguous float64 array, read in place), the fastest of R: its time includes the
strategy's setup at each query and the answers' conversion to arrays; it is measured with fresh
result arrays, and with `out=` arrays reused as the Rust side reuses its buffer. Last, the warm
start of a settled solver loop: `Locator.relocate` from the previous answers in `out=`, against
`locate` into the same arrays.
"""

import argparse
import json
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import cgcontact


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--scene", default="sphere-fine")
    args = parser.parse_args()
    cli = os.environ.get("CGCONTACT_BIN", "cgcontact")
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        subprocess.run([cli, "scene", args.scene, "--out", folder], check=True, capture_output=True)
        body = cgcontact.read_mesh(folder / "mesh.vtu")
        scene_points = np.loadtxt(folder / "points.csv", delimiter=",", skiprows=1)
        # Points spread over the scene's box, most of them inside the body.
        low, high = scene_points.min(axis=0), scene_points.max(axis=0)
        rng = np.random.default_rng(1)
        points = low + rng.random((args.points, 3)) * (high - low)
        np.savetxt(folder / "bench.csv", points, delimiter=",", header="x,y,z", comments="",
                   fmt="%.17g")
        points = np.loadtxt(folder / "bench.csv", delimiter=",", skiprows=1)
        rust = json.loads(subprocess.run(
            [cli, "locate", "--mesh", folder / "mesh.vtu", "--points", folder / "bench.csv",
             "--repeat", str(args.repeat), "--json", "-q"],
            check=True, capture_output=True).stdout)
    locator = cgcontact.Locator(body)
    out = locator.locate(points)  # warm-up, and the arrays reused by out=

    def timed(query):
        times = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            query()
            times.append(time.perf_counter() - start)
        return min(times), np.median(times)

    python, python_median = timed(lambda: locator.locate(points))
    reused, reused_median = timed(lambda: locator.locate(points, out=out))
    warm, warm_median = timed(lambda: locator.relocate(points, out=out))
    cell = out[0]
    assert (cell >= 0).sum() == rust["located"], "Python and the CLI disagree"
    rust_rate = rust["points"] / rust["query_seconds_min"]
    python_rate = len(points) / python
    print(f"{len(points)} points, {rust['located']} located, {rust['threads']} threads")
    print(f"rust library: {rust['query_seconds_min'] * 1e3:.1f} ms, {rust_rate:.3e} points/s")
    print(f"python, new arrays:   {python * 1e3:.1f} ms, {python_rate:.3e} points/s, "
          f"{python_rate / rust_rate:.3f} x rust (median {python_median * 1e3:.1f} ms)")
    reused_rate = len(points) / reused
    print(f"python, out= reused:  {reused * 1e3:.1f} ms, {reused_rate:.3e} points/s, "
          f"{reused_rate / rust_rate:.3f} x rust (median {reused_median * 1e3:.1f} ms)")
    warm_rate = len(points) / warm
    print(f"python, relocate:     {warm * 1e3:.1f} ms, {warm_rate:.3e} points/s, "
          f"{warm_rate / reused_rate:.3f} x locate with out= (median {warm_median * 1e3:.1f} ms)")


if __name__ == "__main__":
    main()
