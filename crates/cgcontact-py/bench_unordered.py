"""`Locator.locate` against `Locator.locate_unordered` on a body too large for the caches.

    python crates/cgcontact-py/bench_unordered.py [--points N] [--repeat R] [--threads T]

A 128 x 256 x 128-cell lattice (4.2 M cells, the `scale` bench's largest block) with a smooth
displacement field, N random points in its box (1 M by default), one thread by default. Both
calls write into `out=` arrays reused across calls, as a solver loop does, and are alternated
R times; the fastest and the median of each are printed, with their ratio. On such a body the
library sorts the points by cell: `locate` then puts each answer back at its point's row (a
store to a random place per point), `locate_unordered` leaves them in the order found.
"""

import argparse
import time

import numpy as np

import cgcontact


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    counts = (128, 256, 128)
    h = 5.0 / 128
    body = cgcontact.Body((0.0, 0.0, 0.0), (h, h, h), counts)
    k, j, i = np.meshgrid(*(np.arange(c + 1) for c in counts[::-1]), indexing="ij")
    x, y, z = (a.ravel() * h for a in (i, j, k))
    u = np.column_stack([0.1 * h * np.sin(y), 0.1 * h * np.cos(x) * z, -0.1 * h * np.sin(x + z)])
    body.set_displacements(u)
    del x, y, z, u, i, j, k
    rng = np.random.default_rng(1)
    size = np.array(counts) * h
    points = rng.random((args.points, 3)) * size
    locator = cgcontact.Locator(body, threads=args.threads)
    n = args.points
    ordered = locator.locate(points)
    unordered = locator.locate_unordered(points)
    assert (unordered[1] == ordered[0][unordered[0]]).all()
    times = {"locate": [], "locate_unordered": []}
    for _ in range(args.repeat):
        for name, query in (("locate", lambda: locator.locate(points, out=ordered)),
                            ("locate_unordered",
                             lambda: locator.locate_unordered(points, out=unordered))):
            start = time.perf_counter()
            query()
            times[name].append(time.perf_counter() - start)
    for name, t in times.items():
        print(f"{name}: {n / min(t) / 1e6:.2f} M points/s best, "
              f"{n / np.median(t) / 1e6:.2f} median ({args.threads} thread(s), {n} points)")
    ratio = min(times["locate"]) / min(times["locate_unordered"])
    print(f"locate_unordered / locate: {ratio:.2f}x (best of {args.repeat})")


if __name__ == "__main__":
    main()
