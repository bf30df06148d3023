"""The Python bindings against the command line on generated scenes, and on small bodies whose
answers are known.

The command line binary is $CGCONTACT_BIN; without it, the workspace's release binary is built
with cargo. Run with `pytest crates/cgcontact-py/tests` once the module is installed.
"""

import ast
import inspect
import json
import os
import pathlib
import subprocess
import sys
import threading
import time
import tracemalloc
import warnings

import numpy as np
import pytest

import cgcontact

ROOT = pathlib.Path(__file__).resolve().parents[3]
STRATEGIES = ["lattice", "centroid", "noderad", "noderad-seed", "rtree", "brute"]
# Every STRIDE-th point for the strategy comparison: brute force tries every cell.
STRIDE = 40
GAP_DISTANCE = 0.3


@pytest.fixture(scope="session")
def cli():
    """The command line binary."""
    given = os.environ.get("CGCONTACT_BIN")
    if given:
        return given
    subprocess.run(
        ["cargo", "build", "--release", "--locked", "-p", "cgcontact-cli"], cwd=ROOT, check=True
    )
    meta = json.loads(
        subprocess.run(
            ["cargo", "metadata", "--format-version", "1", "--no-deps"],
            cwd=ROOT,
            check=True,
            capture_output=True,
        ).stdout
    )
    return str(pathlib.Path(meta["target_directory"]) / "release" / "cgcontact")


def run(cli, *args):
    subprocess.run([cli, *map(str, args)], check=True, capture_output=True)


def read_csv(path):
    """A results CSV as a structured array; empty fields (gap columns) read as NaN."""
    return np.genfromtxt(path, delimiter=",", names=True, dtype=float)


@pytest.fixture(scope="session", params=["sphere-fine", "sphere-adaptive"])
def scene(request, cli, tmp_path_factory):
    """A generated scene: its folder, body and points."""
    folder = tmp_path_factory.mktemp(request.param)
    run(cli, "scene", request.param, "--out", folder)
    points = np.loadtxt(folder / "points.csv", delimiter=",", skiprows=1)
    body = cgcontact.read_mesh(str(folder / "mesh.vtu"))
    return folder, body, points


def test_the_scenes_are_what_they_say(scene):
    folder, body, points = scene
    assert body.is_adaptive == ("adaptive" in folder.name)
    assert points.shape[1] == 3 and len(points) > 10_000


def test_locate_matches_the_command_line(scene, cli):
    folder, body, points = scene
    run(cli, "locate", "--mesh", folder / "mesh.vtu", "--points", folder / "points.csv",
        "--out", folder / "results.csv", "-q")
    expected = read_csv(folder / "results.csv")
    cell, xi = cgcontact.Locator(body).locate(points)
    assert cell.dtype == np.int64 and xi.dtype == np.float64 and xi.shape == (len(points), 3)
    np.testing.assert_array_equal(cell, expected["cell"].astype(np.int64))
    want = np.column_stack([expected["xi"], expected["eta"], expected["zeta"]])
    np.testing.assert_array_equal(np.isnan(xi), np.isnan(want))
    np.testing.assert_allclose(xi, want, rtol=0, atol=1e-12, equal_nan=True)
    assert (cell >= 0).sum() > len(points) // 2


def test_located_points_match_the_known_answers(scene):
    folder, body, points = scene
    known = read_csv(folder / "known.csv")
    rows = known["point"].astype(int)
    cell, xi = cgcontact.Locator(body).locate(points[rows])
    np.testing.assert_array_equal(cell, known["cell"].astype(np.int64))
    want = np.column_stack([known["xi"], known["eta"], known["zeta"]])
    np.testing.assert_allclose(xi, want, rtol=0, atol=1e-8)


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_every_strategy_matches_the_command_line(scene, cli, strategy):
    folder, body, points = scene
    subset = folder / "subset.csv"
    if not subset.exists():
        np.savetxt(subset, points[::STRIDE], delimiter=",", header="x,y,z", comments="",
                   fmt="%.17g")
    out = folder / f"results-{strategy}.csv"
    run(cli, "locate", "--mesh", folder / "mesh.vtu", "--points", subset, "--out", out,
        "--strategy", strategy, "-q")
    expected = read_csv(out)
    locator = cgcontact.Locator(body, strategy=strategy)
    assert locator.strategy == strategy
    cell, xi = locator.locate(np.loadtxt(subset, delimiter=",", skiprows=1))
    np.testing.assert_array_equal(cell, expected["cell"].astype(np.int64))
    want = np.column_stack([expected["xi"], expected["eta"], expected["zeta"]])
    np.testing.assert_allclose(xi, want, rtol=0, atol=1e-12, equal_nan=True)


def test_gap_matches_the_command_line(scene, cli):
    folder, body, points = scene
    out = folder / "gap.csv"
    run(cli, "locate", "--mesh", folder / "mesh.vtu", "--points", folder / "points.csv",
        "--out", out, "--gap", GAP_DISTANCE, "-q")
    expected = read_csv(out)
    got = cgcontact.Locator(body).gap(points, GAP_DISTANCE)
    assert got["face_cell"].dtype == np.int64 and got["face"].dtype == np.int32
    np.testing.assert_allclose(got["gap"], expected["gap"], rtol=0, atol=1e-12, equal_nan=True)
    for name, columns in [("closest", ["cx", "cy", "cz"]), ("normal", ["nx", "ny", "nz"])]:
        want = np.column_stack([expected[c] for c in columns])
        np.testing.assert_allclose(got[name], want, rtol=0, atol=1e-12, equal_nan=True)
    for name in ["face_cell", "face"]:
        want = np.nan_to_num(expected[name], nan=-1).astype(np.int64)
        np.testing.assert_array_equal(got[name], want)
    within = ~np.isnan(got["gap"])
    assert within.any() and (~within).any() and (got["gap"][within] < 0).any()


def test_owners_match_the_command_line(scene, cli):
    folder, body, points = scene
    out = folder / "owners.csv"
    run(cli, "locate", "--mesh", folder / "mesh.vtu", "--points", folder / "points.csv",
        "--out", out, "--all-owners", "-q")
    expected = read_csv(out)
    lists = cgcontact.Locator(body).locate_owners(points)
    assert len(lists) == len(points)
    rows = [(p, c, x) for p, owners in enumerate(lists) for c, x in owners]
    # The command line keeps one row with cell -1 for a point without owners.
    rows += [(p, -1, (np.nan,) * 3) for p, owners in enumerate(lists) if not owners]
    rows.sort(key=lambda r: (r[0], r[1]))
    np.testing.assert_array_equal([r[0] for r in rows], expected["point"].astype(int))
    np.testing.assert_array_equal([r[1] for r in rows], expected["cell"].astype(int))
    want = np.column_stack([expected["xi"], expected["eta"], expected["zeta"]])
    np.testing.assert_allclose([r[2] for r in rows], want, rtol=0, atol=1e-12, equal_nan=True)


def test_read_mesh_without_its_displacement_is_undeformed(scene):
    folder, body, points = scene
    undeformed = cgcontact.read_mesh(str(folder / "mesh.vtu"), displacement=None)
    a, _ = cgcontact.Locator(body).locate(points)
    b, _ = cgcontact.Locator(undeformed).locate(points)
    assert (a != b).any()
    with pytest.raises(ValueError, match="no_such_array"):
        cgcontact.read_mesh(str(folder / "mesh.vtu"), displacement="no_such_array")


def test_a_file_the_system_refuses_raises_the_oserror_of_its_errno(scene, tmp_path):
    """A missing mesh raised ValueError, which `except FileNotFoundError` (or OSError) misses;
    each refusal of the operating system is now the OSError Python gives for its errno, with the
    file's name, while a file that is no mesh stays a ValueError."""
    folder, _, _ = scene
    missing = tmp_path / "no" / "mesh.vtu"
    with pytest.raises(FileNotFoundError) as raised:
        cgcontact.read_mesh(missing)
    assert raised.value.errno == 2 and raised.value.filename == str(missing)
    assert raised.value.strerror == "No such file or directory"
    with pytest.raises(IsADirectoryError):
        cgcontact.read_mesh(tmp_path)
    if os.geteuid() != 0:  # root reads any file
        locked = tmp_path / "locked.vtu"
        locked.write_bytes((folder / "mesh.vtu").read_bytes())
        locked.chmod(0)
        with pytest.raises(PermissionError):
            cgcontact.read_mesh(locked)
    garbage = tmp_path / "garbage.vtu"
    garbage.write_bytes(b"not a mesh")
    with pytest.raises(ValueError, match="garbage.vtu"):
        cgcontact.read_mesh(garbage)


# Small bodies whose answers are known.

ORIGIN, SPACING, COUNTS = (1.0, -2.0, 0.5), (0.5, 0.25, 1.0), (3, 2, 2)


def lattice_hexes():
    """The nodes and VTK hexahedra of the lattice ORIGIN, SPACING, COUNTS (cells x fastest)."""
    nx, ny, nz = COUNTS
    k, j, i = np.meshgrid(np.arange(nz + 1), np.arange(ny + 1), np.arange(nx + 1), indexing="ij")
    nodes = np.column_stack([i.ravel(), j.ravel(), k.ravel()]) * SPACING + ORIGIN
    node = lambda i, j, k: i + (nx + 1) * (j + (ny + 1) * k)
    hexes = []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                hexes.append([node(i, j, k), node(i + 1, j, k), node(i + 1, j + 1, k),
                              node(i, j + 1, k), node(i, j, k + 1), node(i + 1, j, k + 1),
                              node(i + 1, j + 1, k + 1), node(i, j + 1, k + 1)])
    return nodes, np.array(hexes)


def test_float_rounded_nodes_stay_where_given_after_an_update():
    """Nodes stored as 32-bit floats lie off the lattice by more than f64 rounding: the body keeps
    them where the caller has them, as `cgcontact locate` does a file's. An update of the
    displacements dropped those offsets: after `set_displacements(zeros)` the nodes sat at their
    lattice positions, and each point's xi moved by a few 1e-8 (a point on a face where the
    caller's nodes put it could leave its cell)."""
    h, n = 0.1, 3  # (on 2 cells f32's rounding of 0, 0.1 and 0.2 is a lattice itself)
    k, j, i = np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij")
    nodes = (np.column_stack([i.ravel(), j.ravel(), k.ravel()]) * h).astype(np.float32)
    nodes = nodes.astype(np.float64)
    node = lambda i, j, k: i + (n + 1) * (j + (n + 1) * k)
    hexes = [[node(i, j, k), node(i + 1, j, k), node(i + 1, j + 1, k), node(i, j + 1, k),
              node(i, j, k + 1), node(i + 1, j, k + 1), node(i + 1, j + 1, k + 1),
              node(i, j + 1, k + 1)]
             for k in range(n) for j in range(n) for i in range(n)]
    body = cgcontact.Body.from_hexes(nodes, np.array(hexes))
    rng = np.random.default_rng(5)
    points = rng.uniform(0.01, 0.29, (200, 3))
    points[::2, 2] = nodes[node(0, 0, 1), 2]  # on the faces between the first two layers
    locator = cgcontact.Locator(body)
    cells, xi = locator.locate(points)
    assert (cells >= 0).all()
    body.set_displacements(np.zeros((len(nodes), 3)))
    after = locator.locate(points)
    np.testing.assert_array_equal(after[0], cells)
    np.testing.assert_allclose(after[1], xi, rtol=0, atol=1e-12)
    # A translation moves the caller's nodes, not the lattice's.
    t = np.array([0.0, 0.0, 0.25])
    body.set_displacements(np.tile(t, (len(nodes), 1)))
    moved = locator.locate(points + t)
    np.testing.assert_array_equal(moved[0], cells)
    np.testing.assert_allclose(moved[1], xi, rtol=0, atol=1e-12)


def cell_points():
    """A point in each lattice cell at a known xi, and the cells and xi."""
    nx, ny, nz = COUNTS
    xi = np.array([0.25, -0.5, 0.75])
    cells, points = [], []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                cells.append(i + nx * (j + ny * k))
                points.append(ORIGIN + (np.array([i, j, k]) + (xi + 1) / 2) * SPACING)
    return np.array(points), np.array(cells), xi


def test_a_lattice_body_and_the_same_hexes_answer_alike():
    points, cells, xi = cell_points()
    nodes, hexes = lattice_hexes()
    for body in [cgcontact.Body(ORIGIN, SPACING, COUNTS), cgcontact.Body.from_hexes(nodes, hexes)]:
        cell, got = cgcontact.Locator(body).locate(points)
        np.testing.assert_array_equal(cell, cells)
        np.testing.assert_allclose(got, np.tile(xi, (len(cells), 1)), atol=1e-12)
        assert body.node_count == len(nodes) and body.cell_count == len(hexes)


def test_nodes_printed_with_11_digits_make_the_lattice_they_print():
    """Nodes as VTK's legacy ASCII writer prints doubles (11 significant digits): a lattice of
    spacing 1/3 near 1000 lies up to 5e-8 off its positions. It reads, and each cell's point is
    found there; cells too small for such digits far from the origin are refused saying so."""
    points, cells, xi = cell_points()
    nodes, hexes = lattice_hexes()
    third = np.array([1 / 3, 1 / 3, 1 / 3]) / np.array(SPACING)
    place = lambda p: (p - np.array(ORIGIN)) * third + 1000.0
    print11 = np.vectorize(lambda v: float(f"{v:.10e}"))
    body = cgcontact.Body.from_hexes(print11(place(nodes)), hexes)
    cell, got = cgcontact.Locator(body).locate(place(points))
    np.testing.assert_array_equal(cell, cells)
    np.testing.assert_allclose(got, np.tile(xi, (len(cells), 1)), atol=1e-6)
    far = (place(nodes) - 1000.0) * 1e-4 + 2e6
    with pytest.raises(ValueError, match="printed with 11 significant digits.*too coarse"):
        cgcontact.Body.from_hexes(print11(far), hexes)


def test_displacements_move_the_cells():
    points, cells, xi = cell_points()
    nodes, hexes = lattice_hexes()
    shift = np.array([0.01, -0.02, 0.03])
    for body in [cgcontact.Body(ORIGIN, SPACING, COUNTS), cgcontact.Body.from_hexes(nodes, hexes)]:
        locator = cgcontact.Locator(body)
        body.set_displacements(np.tile(shift, (body.node_count, 1)))
        cell, got = locator.locate(points + shift)
        np.testing.assert_array_equal(cell, cells)
        np.testing.assert_allclose(got, np.tile(xi, (len(cells), 1)), atol=1e-9)


def test_inactive_cells_hold_nothing():
    points, cells, _ = cell_points()
    active = np.ones(len(cells), dtype=bool)
    active[[0, 5]] = False
    cell, xi = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS, active)).locate(points)
    np.testing.assert_array_equal(cell, np.where(active, cells, -1))
    assert np.isnan(xi[~active]).all()


def test_active_flags_in_lattice_shape_and_as_numbers():
    points, cells, _ = cell_points()
    nx, ny, nz = COUNTS
    active = (np.arange(len(cells)) % 3 != 0).astype(np.int64)
    for given in [active, active.reshape(nz, ny, nx), active.astype(float), active.astype(bool)]:
        body = cgcontact.Body(ORIGIN, SPACING, COUNTS, given)
        cell, _ = cgcontact.Locator(body).locate(points)
        np.testing.assert_array_equal(cell, np.where(active == 1, cells, -1))


def test_a_point_on_a_node_has_eight_owners():
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    node = np.array(ORIGIN) + np.array(SPACING) * (1, 1, 1)
    owners = cgcontact.Locator(body).locate_owners(node)
    assert sorted(c for c, _ in owners) == [0, 1, 3, 4, 6, 7, 9, 10]
    assert all(np.allclose(np.abs(x), 1) for _, x in owners)
    assert cgcontact.Locator(body).locate_owners(node - 100) == []


def test_owners_come_in_ascending_order_of_the_callers_cells():
    """`locate_owners` sorted the owners by the body's own cell order, then renumbered them as the
    caller's: with the hexahedra given in reverse, a node's owners came in descending order."""
    nodes, hexes = lattice_hexes()
    body = cgcontact.Body.from_hexes(nodes, hexes[::-1])
    node = np.array(ORIGIN) + np.array(SPACING) * (1, 1, 1)
    owners = cgcontact.Locator(body).locate_owners(node)
    cells = [c for c, _ in owners]
    assert cells == sorted(cells) and len(cells) == 8, cells
    for points in [np.array([node]), np.array([node, node + np.array(SPACING) * (1, 0, 0)])]:
        for listed in cgcontact.Locator(body).locate_owners(points):
            assert [c for c, _ in listed] == sorted(c for c, _ in listed)


def test_precision_threads_and_inputs_converted_answer_alike():
    points, cells, xi = cell_points()
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    for locator in [cgcontact.Locator(body, precision="f32"), cgcontact.Locator(body, threads=1),
                    cgcontact.Locator(body, tol=1e-12, max_iter=30)]:
        for given in [points, points.tolist(), np.asfortranarray(points),
                      points.astype(np.float32), points[:, [0, 1, 2]]]:
            cell, got = locator.locate(given)
            np.testing.assert_array_equal(cell, cells)
            np.testing.assert_allclose(got, np.tile(xi, (len(cells), 1)), atol=1e-4)
    cell, got = cgcontact.Locator(body).locate(np.empty((0, 3)))
    assert cell.shape == (0,) and got.shape == (0, 3)


def test_locate_writes_into_out_arrays():
    points, cells, xi = cell_points()
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    out = (np.full(len(points), 7, dtype=np.int64), np.zeros((len(points), 3)))
    cell, got = locator.locate(points, out=out)
    assert cell is out[0] and got is out[1]
    np.testing.assert_array_equal(out[0], cells)
    np.testing.assert_allclose(out[1], np.tile(xi, (len(cells), 1)), atol=1e-12)
    with pytest.raises(ValueError, match="out must be"):
        locator.locate(points, out=(out[0][:-1], out[1][:-1]))
    with pytest.raises(ValueError, match="out must be"):
        locator.locate(points, out=(out[0], np.asfortranarray(out[1])))


def test_gap_on_a_block_is_the_distance_to_its_faces():
    body = cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 2, 2))
    points = np.array([[1.0, 1.0, 2.5], [0.5, 1.0, 1.0], [5.0, 5.0, 5.0]])
    got = cgcontact.Locator(body).gap(points, 1.0)
    np.testing.assert_allclose(got["gap"][:2], [0.5, -0.5], atol=1e-12)
    np.testing.assert_allclose(got["closest"][0], [1, 1, 2], atol=1e-12)
    np.testing.assert_allclose(got["normal"][0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(got["normal"][1], [-1, 0, 0], atol=1e-12)
    assert np.isnan(got["gap"][2]) and got["face_cell"][2] == -1 and got["face"][2] == -1
    assert got["face"][1] == 0


def test_a_c_contiguous_float64_array_is_read_in_place():
    """The documented probe: `_data_address` returns the address the bindings read from."""
    points, _, _ = cell_points()
    assert points.flags.c_contiguous and points.dtype == np.float64
    assert cgcontact._data_address(points) == points.__array_interface__["data"][0]
    # A view starting at a later row is read in place too.
    assert cgcontact._data_address(points[2:]) == points[2:].__array_interface__["data"][0]
    # Anything else is converted: Fortran order, float32, a list.
    for other in [np.asfortranarray(points), points.astype(np.float32)]:
        assert cgcontact._data_address(other) != other.__array_interface__["data"][0]
    cgcontact._data_address(points.tolist())


def test_queries_release_the_gil():
    """Queries in several Python threads at once answer as one thread does."""
    points, cells, _ = cell_points()
    points = np.repeat(points, 2000, axis=0)
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS), threads=1)
    results = [None] * 4

    def work(k):
        results[k] = locator.locate(points)[0]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for cell in results:
        np.testing.assert_array_equal(cell, np.repeat(cells, 2000))


# Bad input: ValueError naming what is wrong, never a panic.


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda l, b: l.locate(np.zeros((4, 2))), r"shape \(n, 3\)"),
        (lambda l, b: l.locate(np.zeros(3)), r"shape \(n, 3\)"),
        (lambda l, b: l.locate([[0, 0, 0], [0, np.nan, 0]]), "row 1"),
        (lambda l, b: l.locate_owners([0, np.inf, 0]), "row 0"),
        (lambda l, b: l.gap([[0, 0, 0], [1, 1, 1], [np.nan, 0, 0]], 1.0), "row 2"),
        (lambda l, b: l.gap(np.zeros((1, 3)), -1.0), "distance"),
        (lambda l, b: l.gap(np.zeros((1, 3)), np.inf), "distance"),
        (lambda l, b: l.locate([["a", "b", "c"]]), None),
        (lambda l, b: b.set_displacements(np.zeros((5, 3))), "got 5 rows"),
        (lambda l, b: b.set_displacements(np.where(np.arange(36 * 3).reshape(36, 3) == 31, np.nan, 0)),
         "row 10"),
        (lambda l, b: cgcontact.Locator(b, strategy="kdtree"), "kdtree"),
        (lambda l, b: cgcontact.Locator(b, precision="f16"), "f16"),
        (lambda l, b: cgcontact.Locator(b, tol=-1.0), None),
        (lambda l, b: cgcontact.Locator(b, max_iter=0), None),
        (lambda l, b: cgcontact.Locator(b, threads=0), "threads"),
        (lambda l, b: cgcontact.Locator(b, threads=1025), "at most 1024"),
        (lambda l, b: cgcontact.Body((0, 0, 0), (0, 1, 1), (1, 1, 1)), None),
        (lambda l, b: cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 2, 2), active=[True] * 7),
         r"shape \(8,\)"),
        # (nx, ny, nz) instead of (nz, ny, nx): as many flags, read transposed.
        (lambda l, b: cgcontact.Body((0, 0, 0), (1, 1, 1), (3, 2, 1), active=np.ones((3, 2, 1))),
         r"\(nz, ny, nx\) = \(1, 2, 3\)"),
        (lambda l, b: cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 1, 1), active=[1, 2]), "0s and 1s"),
        # Node numbers that are not whole: numpy's int64 conversion truncated 0.5 to node 0.
        (lambda l, b: cgcontact.Body.from_hexes(lattice_hexes()[0], lattice_hexes()[1] + 0.5),
         "whole node numbers"),
        (lambda l, b: cgcontact.Body.from_hexes(lattice_hexes()[0],
                                                np.where(lattice_hexes()[1] == 3, np.nan,
                                                         lattice_hexes()[1])),
         "whole node numbers"),
        (lambda l, b: l.locate(np.zeros((2, 3)), out=(np.zeros(2, np.int32), np.zeros((2, 3)))),
         r"got \(int32 array of shape \(2,\); float64 array of shape \(2, 3\)\)"),
        (lambda l, b: cgcontact.Body((np.nan, 0, 0), (1, 1, 1), (1, 1, 1)), "not finite"),
        (lambda l, b: cgcontact.Body.from_hexes(lattice_hexes()[0], lattice_hexes()[1] + 100),
         "hexes row 0 corner 0"),
        (lambda l, b: cgcontact.Body.from_hexes(lattice_hexes()[0], lattice_hexes()[1][:, :4]),
         r"shape \(n, 8\)"),
        (lambda l, b: cgcontact.Body.from_hexes(np.where(np.arange(36 * 3).reshape(36, 3) == 7,
                                                         np.nan, lattice_hexes()[0]),
                                                lattice_hexes()[1]), "nodes row 2"),
        (lambda l, b: cgcontact.Body.from_hexes(np.zeros((8, 3)), np.zeros((0, 8))), "no cell"),
        (lambda l, b: cgcontact.Body.from_hexes(lattice_hexes()[0] * [1, 1, 0], lattice_hexes()[1]), None),
    ],
)
def test_bad_input_raises_value_error(call, message):
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    with pytest.raises(ValueError, match=message):
        call(cgcontact.Locator(body), body)


# Inputs numpy would silently reinterpret, and arrays Rust must not read in place.


def misaligned(values):
    """A C-contiguous copy of `values` one byte past an aligned address (numpy's ALIGNED flag off),
    as a view into a byte buffer at an odd offset gives."""
    values = np.ascontiguousarray(values)
    raw = np.zeros(values.nbytes + values.itemsize, dtype=np.uint8)
    array = raw[1:1 + values.nbytes].view(values.dtype).reshape(values.shape)
    array[...] = values
    assert not array.flags.aligned and array.flags.c_contiguous
    return array


def test_complex_and_date_arrays_are_refused_not_cast():
    """numpy's float conversion drops imaginary parts with only a ComplexWarning."""
    points, _, _ = cell_points()
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    locator = cgcontact.Locator(body)
    for given in [points + 0.5j, points.astype(complex), np.zeros((2, 3), "datetime64[s]"),
                  np.zeros((2, 3), "timedelta64[s]")]:
        with pytest.raises(ValueError, match="must hold real numbers"):
            locator.locate(given)
    with pytest.raises(ValueError, match="must hold real numbers"):
        locator.locate_owners(points[0] + 1j)
    with pytest.raises(ValueError, match="must hold real numbers"):
        body.set_displacements(np.zeros((body.node_count, 3)) + 1j)
    with pytest.raises(ValueError, match="must hold real numbers"):
        cgcontact.Body.from_hexes(lattice_hexes()[0] + 0j, lattice_hexes()[1])


def test_boolean_and_text_arrays_are_refused_not_cast():
    """numpy reads booleans as 0 and 1 and parses text ("0.5"): coordinates of neither kind are
    meant, and a column of text is a file not yet read as numbers."""
    points, _, _ = cell_points()
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    locator = cgcontact.Locator(body)
    for given in [points > 0.5, points.astype(str), points.astype(bytes)]:
        for query in [locator.locate, locator.locate_owners, lambda p: locator.gap(p, 0.1)]:
            with pytest.raises(ValueError, match=f"must hold real numbers, got dtype {given.dtype}"):
                query(given)
    with pytest.raises(ValueError, match="must hold real numbers"):
        body.set_displacements(np.zeros((body.node_count, 3), dtype=bool))
    # Numbers of any real kind still are read.
    for given in [points.astype(np.float32), np.rint(points).astype(np.int32), points.astype(object)]:
        np.testing.assert_array_equal(locator.locate(given)[0],
                                      locator.locate(given.astype(float))[0])


def assert_object_element_refused(locator, points, element, shown):
    """`points` as an object array with `element` at [1, 2]: every query refuses it, naming it
    as `shown`."""
    given = points.astype(object)
    given[1, 2] = element
    for query in [locator.locate, locator.locate_owners, lambda p: locator.gap(p, 0.1)]:
        with pytest.raises(ValueError, match="must hold real numbers, got dtype object "
                                             "holding .* at \\[1, 2\\]") as caught:
            query(given)
        assert shown in str(caught.value), str(caught.value)


def test_object_arrays_of_text_booleans_or_complex_are_refused_not_cast():
    """numpy parses the text "3" in an object array (a table read without converting a column)
    as 3.0, reads True as 1 and keeps a complex number's real part: refused as arrays of those
    dtypes are, naming the element. Numbers of any real kind in an object array still are read."""
    points, cells, _ = cell_points()
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    locator = cgcontact.Locator(body)
    for element, shown in [("0.5", "str '0.5'"), (b"0.5", "bytes b'0.5'"), (True, "bool True"),
                           (np.True_, "True"), (0.5 + 0j, "complex (0.5+0j)"),
                           (np.complex128(0.5), "(0.5")]:
        assert_object_element_refused(locator, points, element, shown)
    u = np.zeros((body.node_count, 3), dtype=object)
    u[4, 0] = "0"
    with pytest.raises(ValueError, match=r"u must hold real numbers, got dtype object holding "
                                         r"str '0' at \[4, 0\]"):
        body.set_displacements(u)
    nodes, hexes = lattice_hexes()
    text_node = nodes.astype(object)
    text_node[0, 0] = str(nodes[0, 0])
    with pytest.raises(ValueError, match="nodes must hold real numbers, got dtype object"):
        cgcontact.Body.from_hexes(text_node, hexes)
    text_hex = hexes.astype(object)
    text_hex[0, 3] = str(hexes[0, 3])
    with pytest.raises(ValueError, match=r"hexes must hold integers, got dtype object holding "
                                         r"str .* at \[0, 3\]"):
        cgcontact.Body.from_hexes(nodes, text_hex)
    # Real numbers of any kind, in an object array, are read as before.
    from decimal import Decimal
    from fractions import Fraction
    mixed = points.astype(object)
    mixed[0, 0], mixed[1, 1], mixed[2, 2] = (Fraction(points[0, 0]), Decimal(points[1, 1]),
                                             np.float32(points[2, 2]))
    np.testing.assert_array_equal(locator.locate(mixed)[0], locator.locate(mixed.astype(float))[0])
    cgcontact.Body.from_hexes(nodes, hexes.astype(object))


def test_boolean_hexes_are_refused_not_read_as_nodes_0_and_1():
    """numpy's int64 cast reads True as node 1 and False as node 0, whole numbers both."""
    nodes, hexes = lattice_hexes()
    for given in [hexes > 3, (hexes > 3).tolist()]:
        with pytest.raises(ValueError, match="hexes must hold integers, got dtype bool"):
            cgcontact.Body.from_hexes(nodes, given)
    with pytest.raises(ValueError, match="hexes must hold integers, got dtype <U"):
        cgcontact.Body.from_hexes(nodes, hexes.astype(str))


def test_masked_values_are_refused_not_read_as_data():
    """A masked array's buffer holds values the caller marked as missing."""
    points, cells, _ = cell_points()
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    locator = cgcontact.Locator(body)
    masked = np.ma.masked_array(points, mask=np.zeros(points.shape, dtype=bool))
    np.testing.assert_array_equal(locator.locate(masked)[0], cells)  # no value masked: fine
    masked[1, 2] = np.ma.masked
    for call in [lambda: locator.locate(masked), lambda: locator.locate_owners(masked),
                 lambda: locator.gap(masked, 1.0),
                 lambda: body.set_displacements(np.ma.masked_array(
                     np.zeros((body.node_count, 3)), mask=np.eye(body.node_count, 3)))]:
        with pytest.raises(ValueError, match="masked values"):
            call()
    active = np.ma.masked_array(np.ones(12), mask=[True] + [False] * 11)
    with pytest.raises(ValueError, match="active is a masked array"):
        cgcontact.Body(ORIGIN, SPACING, COUNTS, active)
    nodes, hexes = lattice_hexes()
    with pytest.raises(ValueError, match="hexes is a masked array"):
        cgcontact.Body.from_hexes(nodes, np.ma.masked_array(hexes, mask=hexes == 3))


def test_misaligned_arrays_are_copied_or_refused_not_read_in_place():
    """A misaligned slice is undefined behaviour in Rust (a debug build aborts the interpreter)."""
    points, cells, xi = cell_points()
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    given = misaligned(points)
    assert cgcontact._data_address(given) != given.__array_interface__["data"][0]
    cell, got = locator.locate(given)
    np.testing.assert_array_equal(cell, cells)
    np.testing.assert_allclose(got, np.tile(xi, (len(cells), 1)), atol=1e-12)
    nodes, hexes = lattice_hexes()
    body = cgcontact.Body.from_hexes(misaligned(nodes), misaligned(hexes))
    np.testing.assert_array_equal(cgcontact.Locator(body).locate(points)[0], cells)
    n = len(points)
    for out in [(misaligned(np.zeros(n, np.int64)), np.zeros((n, 3))),
                (np.zeros(n, np.int64), misaligned(np.zeros((n, 3))))]:
        with pytest.raises(ValueError, match="misaligned"):
            locator.locate(points, out=out)


def test_out_errors_name_what_is_wrong():
    points, _, _ = cell_points()
    n = len(points)
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    cells, xi = np.zeros(n, np.int64), np.zeros((n, 3))
    cases = [
        ((cells.reshape(n, 1), xi), rf"int64 array of shape \({n}, 1\); float64"),
        ((cells, xi.reshape(3 * n)), rf"float64 array of shape \({3 * n},\)"),
        ([cells, xi], "got list object"),
        ((cells, np.zeros((n, 6))[:, ::2]), "not C-contiguous"),
    ]
    for out, message in cases:
        with pytest.raises(ValueError, match=message):
            locator.locate(points, out=out)
    readonly = np.zeros((n, 3))
    readonly.setflags(write=False)
    with pytest.raises(ValueError, match="xi array is read-only"):
        locator.locate(points, out=(cells, readonly))
    given = points.copy()
    with pytest.raises(ValueError, match="xi array shares memory with the points"):
        locator.locate(given, out=(cells, given))
    both = np.zeros(3 * n)
    with pytest.raises(ValueError, match="shares memory"):
        locator.locate(points, out=(both[:n].view(np.int64), both.reshape(n, 3)))


def test_shape_errors_name_the_shape_given():
    """numpy.ascontiguousarray made None and scalars arrays of shape (1,)."""
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    for given in [None, 1.0]:
        with pytest.raises(ValueError, match=r"points must have shape \(n, 3\), got \(\)"):
            locator.locate(given)
        with pytest.raises(ValueError, match=r"x must have shape \(3,\) or \(n, 3\), got \(\)"):
            locator.locate_owners(given)
    with pytest.raises(ValueError, match="x row 1"):
        locator.locate_owners([[0, 0, 0], [0, np.nan, 0]])


def test_a_lattice_too_large_for_memory_is_an_error_not_a_killed_interpreter():
    """1625^3 nodes (just under 2^32) take 206 GB: refused before allocating, where the kernel
    refuses such an allocation (Linux's default heuristic overcommit, under 206 GB of memory)."""
    try:
        overcommit = pathlib.Path("/proc/sys/vm/overcommit_memory").read_text().strip()
        meminfo = dict(line.split(":") for line in pathlib.Path("/proc/meminfo").read_text()
                       .splitlines() if ":" in line)
        total_kb = sum(int(meminfo[key].split()[0]) for key in ["MemTotal", "SwapTotal"])
    except (OSError, ValueError, KeyError):
        pytest.skip("not Linux: the allocation probe depends on the kernel's overcommit policy")
    if overcommit != "0" or total_kb > 150 * 2**20:
        pytest.skip("the kernel may grant 206 GB here: the probe cannot refuse it")
    with pytest.raises(MemoryError, match="does not fit in memory"):
        cgcontact.Body((0, 0, 0), (1, 1, 1), (1624, 1624, 1624))


def test_a_displacement_too_large_is_named_by_the_callers_row():
    """The library named its own lattice node: row 0 of nodes given in reverse was 'node 35'."""
    nodes, hexes = lattice_hexes()
    reverse = np.arange(len(nodes))[::-1]
    body = cgcontact.Body.from_hexes(nodes[reverse], reverse[hexes])
    u = np.zeros((body.node_count, 3))
    u[0, 1] = 1e300
    with pytest.raises(ValueError, match=r"displacement row 0 \(0-based\) is too large"):
        body.set_displacements(u)


# Inverted cells: a node moved through its neighbour turns the cells beyond it inside out.

NX, NY, NZ = COUNTS
# Interior node (1, 1, 1) moved 1.5 cells in x, through its neighbour (2, 1, 1): the four cells
# with it at their -x corners, (1, j, k), are inverted there; the four at i = 0 only stretch.
MOVED_NODE = 1 + (NX + 1) * (1 + (NY + 1) * 1)
INVERTED = [1 + NX * (j + NY * k) for k in range(2) for j in range(2)]


def through_neighbour(node_count):
    u = np.zeros((node_count, 3))
    u[MOVED_NODE, 0] = 1.5 * SPACING[0]
    return u


def write_vtk(path, nodes, hexes, u):
    """A legacy ASCII .vtk mesh of hexahedra with its displacement, for `cgcontact locate`."""
    with open(path, "w") as f:
        f.write("# vtk DataFile Version 3.0\ncgcontact python test\nASCII\n"
                "DATASET UNSTRUCTURED_GRID\n")
        f.write(f"POINTS {len(nodes)} double\n")
        f.writelines(f"{x!r} {y!r} {z!r}\n" for x, y, z in nodes.tolist())
        f.write(f"CELLS {len(hexes)} {9 * len(hexes)}\n")
        f.writelines("8 " + " ".join(map(str, corners)) + "\n" for corners in hexes.tolist())
        f.write(f"CELL_TYPES {len(hexes)}\n" + "12\n" * len(hexes))
        f.write(f"POINT_DATA {len(nodes)}\nVECTORS displacement double\n")
        f.writelines(f"{x!r} {y!r} {z!r}\n" for x, y, z in u.tolist())


def cli_inverted_cells(cli, folder, nodes, hexes, u):
    """The `inverted_cells` that `cgcontact locate --json` reports for the mesh, sorted."""
    write_vtk(folder / "mesh.vtk", nodes, hexes, u)
    np.savetxt(folder / "points.csv", nodes[:4], delimiter=",", header="x,y,z", comments="")
    out = subprocess.run([cli, "locate", "--mesh", str(folder / "mesh.vtk"), "--points",
                          str(folder / "points.csv"), "--json", "-q"],
                         check=True, capture_output=True, text=True).stdout
    return sorted(json.loads(out)["inverted_cells"])


def test_no_cell_is_inverted_undeformed_or_mildly_deformed():
    nodes, hexes = lattice_hexes()
    for body in [cgcontact.Body(ORIGIN, SPACING, COUNTS), cgcontact.Body.from_hexes(nodes, hexes)]:
        cells = body.inverted_cells()
        assert cells.dtype == np.int64 and cells.shape == (0,)
        # Every node moved by up to 0.2 of the smallest spacing.
        t = np.arange(body.node_count, dtype=float)[:, None]
        body.set_displacements(0.2 * min(SPACING) * np.sin([0.7, 1.1, 0.3] * t + [0, 1, 2]))
        assert body.inverted_cells().tolist() == []


def test_a_node_moved_through_its_neighbour_inverts_the_cells_beyond_it(cli, tmp_path):
    """Lattice numbering, then the same mesh with nodes and cells shuffled (cells named by their
    row in `hexes`), both against the construction and `cgcontact locate --json`."""
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    body.set_displacements(through_neighbour(body.node_count))
    assert body.inverted_cells().dtype == np.int64
    assert body.inverted_cells().tolist() == INVERTED == [1, 4, 7, 10]
    body.set_displacements(np.zeros((body.node_count, 3)))
    assert body.inverted_cells().tolist() == [], "the list follows the displacements"

    nodes, hexes = lattice_hexes()
    rng = np.random.default_rng(7)
    node_order, cell_order = rng.permutation(len(nodes)), rng.permutation(len(hexes))
    new_node = np.argsort(node_order)       # old node n is new node new_node[n]
    shuffled_nodes, shuffled_hexes = nodes[node_order], new_node[hexes[cell_order]]
    u = through_neighbour(len(nodes))[node_order]
    mesh = cgcontact.Body.from_hexes(shuffled_nodes, shuffled_hexes)
    mesh.set_displacements(u)
    expected = sorted(np.argsort(cell_order)[INVERTED].tolist())  # old cell c is row ...[c]
    assert expected != INVERTED
    assert mesh.inverted_cells().tolist() == expected
    assert cli_inverted_cells(cli, tmp_path, shuffled_nodes, shuffled_hexes, u) == expected


def test_cells_sheared_beyond_the_coordinates_resolution_are_named(cli, tmp_path):
    """Two cells stacked along z at 1e7 from the origin, 1.6e-5 thin along z, u_z = s (Y - Y0):
    with s = 1e3 a rounding of y moves xi_z by about 1.1, both cells are named, as by
    `cgcontact locate --json`; with s = 10, about 0.01, none."""
    origin, spacing = [-1e7] * 3, [0.03125, 0.001953125, 1.5625e-5]
    body = cgcontact.Body(origin, spacing, [1, 1, 2])
    # Lattice order, x fastest: node n has j = (n // 2) % 2.
    j = (np.arange(body.node_count) // 2) % 2
    for shear, expected in [(1e3, [0, 1]), (10.0, [])]:
        u = np.zeros((body.node_count, 3))
        u[:, 2] = shear * j * spacing[1]
        body.set_displacements(u)
        cells = body.unresolved_cells()
        assert cells.dtype == np.int64 and cells.tolist() == expected
        nodes = np.array([[origin[a] + [i, jj, k][a] * spacing[a] for a in range(3)]
                          for k in range(3) for jj in range(2) for i in range(2)])
        hexes = np.array([[0, 1, 3, 2, 4, 5, 7, 6], [4, 5, 7, 6, 8, 9, 11, 10]])
        write_vtk(tmp_path / "mesh.vtk", nodes, hexes, u)
        (tmp_path / "points.csv").write_text("x,y,z\n-1e7,-1e7,-1e7\n")
        out = subprocess.run([cli, "locate", "--mesh", str(tmp_path / "mesh.vtk"), "--points",
                              str(tmp_path / "points.csv"), "--json", "-q"],
                             check=True, capture_output=True, text=True).stdout
        assert sorted(json.loads(out)["unresolved_cells"]) == expected


def test_an_inverted_adaptive_leaf_is_named_by_its_row(cli, tmp_path):
    """Base cells (0, 0, 0) and (1, 0, 0) of a unit lattice, the coarse one first and the other
    halved into 8 leaves (5 hanging nodes on the shared face). The body's corner node at the
    origin, in the leaf at row 1 only, moved 0.75 in x through its neighbour at 0.5: that leaf
    alone is inverted."""
    boxes = [((2, 0, 0), 2)] + [((c & 1, (c >> 1) & 1, (c >> 2) & 1), 1) for c in range(8)]
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                        [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
    positions = np.concatenate([np.array(low) + size * corners for low, size in boxes])
    half_steps, index = np.unique(positions, axis=0, return_inverse=True)
    nodes, hexes = 0.5 * half_steps.astype(float), index.reshape(-1, 8)
    body = cgcontact.Body.from_hexes(nodes, hexes)
    assert body.is_adaptive and body.hanging_count == 5
    assert body.inverted_cells().tolist() == []
    u = np.zeros((len(nodes), 3))
    u[hexes[1, 0], 0] = 0.75
    assert nodes[hexes[1, 0]].tolist() == [0, 0, 0]
    body.set_displacements(u)
    assert body.inverted_cells().tolist() == [1]
    assert cli_inverted_cells(cli, tmp_path, nodes, hexes, u) == [1]


# Warm starts: relocate from the previous answers.


def reversed_hexes_body():
    """The lattice as hexes listed in reverse: caller's cell c is lattice cell count - 1 - c."""
    nodes, hexes = lattice_hexes()
    return cgcontact.Body.from_hexes(nodes, hexes[::-1].copy()), len(hexes)


def test_relocate_answers_as_locate_from_any_hint():
    points, cells, xi = cell_points()
    n = len(points)
    mesh, count = reversed_hexes_body()
    for body, numbered in [(cgcontact.Body(ORIGIN, SPACING, COUNTS), cells),
                           (mesh, count - 1 - cells)]:
        locator = cgcontact.Locator(body)
        previous = locator.locate(points)
        # The next iteration: every node moved, the points with them.
        shift = np.array([0.02, -0.01, 0.04])
        body.set_displacements(np.tile(shift, (body.node_count, 1)))
        moved = points + shift
        cold = locator.locate(moved)
        np.testing.assert_array_equal(cold[0], numbered)
        hints = {
            "previous answers": (previous[0].copy(), previous[1].copy()),
            "none": (np.full(n, -1, dtype=np.int64), np.full((n, 3), np.nan)),
            "wrong cells": ((np.arange(n, dtype=np.int64) * 5) % count, np.full((n, 3), 0.3)),
            "NaN xi": (previous[0].copy(), np.full((n, 3), np.nan)),
        }
        for what, out in hints.items():
            cell, got = locator.relocate(moved, out=out)
            assert cell is out[0] and got is out[1], what
            np.testing.assert_array_equal(cell, numbered, err_msg=what)
            np.testing.assert_allclose(got, cold[1], atol=1e-12, err_msg=what)
            np.testing.assert_allclose(got, np.tile(xi, (n, 1)), atol=1e-9, err_msg=what)
            if what == "none":
                np.testing.assert_array_equal(got, cold[1])


def test_relocate_tries_the_hinted_cell_in_the_callers_numbering():
    node = np.array(ORIGIN) + np.array(SPACING) * (1, 1, 1)  # a node of 8 cells
    owners = [0, 1, 3, 4, 6, 7, 9, 10]
    mesh, count = reversed_hexes_body()
    for body, number in [(cgcontact.Body(ORIGIN, SPACING, COUNTS), lambda c: c),
                         (mesh, lambda c: count - 1 - c)]:
        locator = cgcontact.Locator(body)
        for c in owners:
            out = (np.array([number(c)], dtype=np.int64), np.zeros((1, 3)))
            cell, got = locator.relocate(node[None, :], out=out)
            assert cell[0] == number(c), (cell[0], number(c))
            np.testing.assert_allclose(np.abs(got), 1, atol=1e-12)


def test_relocate_refuses_hints_that_are_no_cell():
    points, cells, _ = cell_points()
    n = len(points)
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    for bad in [-2, len(cells), np.iinfo(np.int64).max]:
        out = (cells.astype(np.int64), np.zeros((n, 3)))
        out[0][3] = bad
        before = (out[0].copy(), out[1].copy())
        with pytest.raises(ValueError, match=f"row 3 \\(0-based\\) is {bad}, not a previous answer: "
                                             f"cells are numbered 0 to {len(cells) - 1}"):
            locator.relocate(points, out=out)
        np.testing.assert_array_equal(out[0], before[0])
        np.testing.assert_array_equal(out[1], before[1])
    with pytest.raises(TypeError):
        locator.relocate(points)
    with pytest.raises(ValueError, match="out must be"):
        locator.relocate(points, out=(cells[:-1].astype(np.int64), np.zeros((n - 1, 3))))
    with pytest.raises(ValueError, match="row 1 \\(0-based\\) is not finite"):
        locator.relocate(np.vstack([points[:1], [np.nan, 0, 0]]),
                         out=(np.full(2, -1, dtype=np.int64), np.zeros((2, 3))))


def test_a_point_not_finite_is_refused_before_anything_is_written():
    """Regression: a NaN point was refused after every row of `out` was written, so a solver
    loop that caught the ValueError had lost its hints (relocate) or previous answers."""
    points, cells, _ = cell_points()
    n = len(points)
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    for bad in [np.nan, np.inf, -np.inf]:
        moved = points.copy()
        moved[n - 1, 2] = bad
        for query in ["locate", "relocate", "locate_unordered"]:
            if query == "locate_unordered":
                out = (np.arange(n, dtype=np.int64), cells.astype(np.int64), np.full((n, 3), 0.25))
            else:
                out = (cells.astype(np.int64), np.full((n, 3), 0.25))
            before = [a.copy() for a in out]
            with pytest.raises(ValueError, match=f"row {n - 1} \\(0-based\\) is not finite"):
                getattr(locator, query)(moved, out=out)
            for got, was in zip(out, before):
                np.testing.assert_array_equal(got, was, err_msg=f"{query} {bad}")


# Hanging nodes off their constraint: the command line's message, warning or error.


def coarse_beside_refined():
    """A unit cell at x in [0, 1] beside one split in 8: nodes, hexes, and the 5 hanging nodes."""
    fine = [(x, y, z) for z in (0, 0.5, 1) for y in (0, 0.5, 1) for x in (1, 1.5, 2)]
    nodes = np.array([(0.0, y, z) for z in (0, 1) for y in (0, 1)] + fine, dtype=float)
    index = {tuple(p): i for i, p in enumerate(nodes.tolist())}
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    hexes = [[index[(float(a), float(b), float(c))] for a, b, c in corners]]
    for k in range(2):
        for j in range(2):
            for i in range(2):
                low = (1 + 0.5 * i, 0.5 * j, 0.5 * k)
                hexes.append([index[(low[0] + 0.5 * a, low[1] + 0.5 * b, low[2] + 0.5 * c)]
                              for a, b, c in corners])
    hanging = [index[p] for p in [(1.0, 0.5, 0.0), (1.0, 0.0, 0.5), (1.0, 0.5, 0.5),
                                  (1.0, 1.0, 0.5), (1.0, 0.5, 1.0)]]
    return nodes, np.array(hexes), hanging


def test_a_hanging_node_off_its_constraint_is_warned_or_refused_as_the_cli_does(cli, tmp_path):
    nodes, hexes, hanging = coarse_beside_refined()
    u = np.zeros_like(nodes)
    u[hanging[2], 0] = 0.01  # the face centre leaves the coarse face
    mesh = tmp_path / "mesh.vtk"
    write_vtk(mesh, nodes, hexes, u)
    np.savetxt(tmp_path / "points.csv", nodes[:1], delimiter=",", header="x,y,z", comments="")
    cli_run = subprocess.run([cli, "locate", "--mesh", str(mesh), "--points",
                              str(tmp_path / "points.csv"), "--out", str(tmp_path / "out.csv")],
                             capture_output=True, text=True)
    assert cli_run.returncode == 0
    with pytest.warns(UserWarning) as caught:
        body = cgcontact.read_mesh(mesh)
    message = str(caught[0].message)
    assert "1 of 5 hanging nodes break their constraint" in message and "by 1.000e-2" in message
    assert message in cli_run.stderr, (message, cli_run.stderr)
    assert body.cell_count == 9
    with pytest.raises(ValueError, match="1 of 5 hanging nodes break their constraint"):
        cgcontact.read_mesh(mesh, strict=True)
    # On the constraint (the mean of the face's corners): read without a word, strict or not.
    u[hanging[2], 0] = 0.0
    write_vtk(mesh, nodes, hexes, u)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cgcontact.read_mesh(mesh, strict=True)


def test_fill_hanging_ignores_the_values_given_at_hanging_nodes():
    """With fill_hanging=True the hanging nodes take their constraints' values, whatever finite
    values their rows held (a solver that leaves them unset): a value there beyond the body's
    limit is not refused, as the C API does not refuse it, and the body answers as with the
    constraints' values given. A NaN there is still refused, as everywhere."""
    nodes, hexes, hanging = coarse_beside_refined()
    exact = cgcontact.Body.from_hexes(nodes, hexes)
    filled = cgcontact.Body.from_hexes(nodes, hexes)
    # A linear field: every hanging node's constraint value is the field at the node.
    def field(x):
        return np.stack([0.02 * x[:, 1], -0.01 * x[:, 2], 0.03 * x[:, 0]], axis=1)

    u = field(nodes)
    exact.set_displacements(u)
    garbage = u.copy()
    garbage[hanging] = 1e300
    filled.set_displacements(garbage, fill_hanging=True)
    inside = 0.03 + nodes * [0.95, 0.9, 0.9]
    points = inside + field(inside)
    cells_exact, xi_exact = cgcontact.Locator(exact).locate(points)
    cells_filled, xi_filled = cgcontact.Locator(filled).locate(points)
    assert (cells_exact >= 0).all()
    np.testing.assert_array_equal(cells_filled, cells_exact)
    np.testing.assert_array_equal(xi_filled, xi_exact)
    with pytest.raises(ValueError, match="5 of 5 hanging nodes break their constraint"):
        filled.set_displacements(garbage)
    garbage[hanging[0]] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        filled.set_displacements(garbage, fill_hanging=True)


def test_an_anisotropic_mesh_vtk_wrote_reads_strictly():
    """Cells of 1 : 1e-3 : 0.1 written by VTK's legacy ASCII writer (11 digits): each axis's
    constraint is checked against its own spacing, so the rounding is not a broken node."""
    path = ROOT / "fixtures" / "vtk-written-adaptive" / "aniso-1e3.legacy-ascii.vtk"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        body = cgcontact.read_mesh(path, strict=True)
    assert body.cell_count > 0


# Several Python threads on one body and its locators.


def test_queries_and_updates_from_several_threads_do_not_deadlock():
    """A locator with a pool of its own took the body's lock on a pool worker: a worker waiting
    for its piece of one query ran another query's job, whose lock waited behind a waiting update,
    which waited for the first query. Two queries and an update, looped, hung in a few calls."""
    body = cgcontact.Body((0, 0, 0), (1, 1, 1), (20, 20, 20))
    points = np.random.default_rng(3).uniform(0, 20, (100_000, 3))
    expected = cgcontact.Locator(body, threads=1).locate(points)[0]
    shift = np.zeros((body.node_count, 3))
    for locator in [cgcontact.Locator(body, threads=2), cgcontact.Locator(body, threads=3)]:
        failures, stop = [], threading.Event()

        def loop(call):
            try:
                while not stop.is_set():
                    call()
            except BaseException as e:  # noqa: BLE001: reported below
                failures.append(e)

        calls = [lambda: np.testing.assert_array_equal(locator.locate(points)[0], expected),
                 lambda: locator.gap(points[:20_000], 0.5),
                 lambda: locator.locate_owners(points[:5_000]),
                 lambda: body.set_displacements(shift)]
        threads = [threading.Thread(target=loop, args=(call,), daemon=True) for call in calls]
        for t in threads:
            t.start()
        stop.wait(3.0)
        stop.set()
        deadline = time.monotonic() + 20.0
        for t in threads:
            t.join(timeout=max(0.0, deadline - time.monotonic()))
        assert not any(t.is_alive() for t in threads), "a query or an update never returned"
        assert failures == []


def test_owners_with_the_seeds_newton_are_refused_as_the_cli_refuses_them(scene, cli):
    """The seed's Newton stops at a residual of 0.1 and tests |xi| <= 1 without tolerance: on the
    adaptive scene it gave 1075 of 3340 points fewer owners than the exact Newton, silently."""
    folder, body, points = scene
    refused = subprocess.run([cli, "locate", "--mesh", folder / "mesh.vtu", "--points",
                              folder / "points.csv", "--all-owners", "--strategy", "noderad-seed",
                              "-q"], capture_output=True, text=True)
    assert refused.returncode == 2 and "noderad-seed" in refused.stderr
    locator = cgcontact.Locator(body, strategy="noderad-seed")
    for x in [points[0], points[:10]]:
        with pytest.raises(ValueError, match="noderad-seed"):
            locator.locate_owners(x)
    # Its single-cell queries stay those of the command line (test_every_strategy_...).
    assert locator.locate(points[:10])[0].shape == (10,)


def test_a_nan_displacement_at_a_node_no_cell_uses_is_refused_as_the_cli_refuses_it(cli, tmp_path):
    """Rows of nodes outside every (active) cell were never read: a NaN there passed silently,
    where `cgcontact locate` refuses it in the file and `from_hexes` refuses it in `nodes`."""
    nodes, hexes = lattice_hexes()
    nodes = np.vstack([nodes, [[9.0, 9.0, 9.0]]])  # node 36: in no cell
    u = np.zeros((len(nodes), 3))
    u[36, 1] = np.nan
    write_vtk(tmp_path / "mesh.vtk", nodes, hexes, u)
    np.savetxt(tmp_path / "points.csv", nodes[:2], delimiter=",", header="x,y,z", comments="")
    cli_run = subprocess.run([cli, "locate", "--mesh", str(tmp_path / "mesh.vtk"), "--points",
                              str(tmp_path / "points.csv"), "-q"], capture_output=True, text=True)
    assert cli_run.returncode == 2, cli_run.stderr
    body = cgcontact.Body.from_hexes(nodes, hexes)
    lattice = cgcontact.Body(ORIGIN, SPACING, COUNTS, active=np.arange(12) != 11)
    v = np.zeros((lattice.node_count, 3))
    v[-1, 0] = np.inf  # the last lattice node: a corner of the inactive cell 11 only
    for target, values, row in [(body, u, 36), (lattice, v, lattice.node_count - 1)]:
        with pytest.raises(ValueError, match=rf"displacement row {row} \(0-based\) is not finite"):
            target.set_displacements(values)
        assert np.isnan(cgcontact.Locator(target).locate(nodes[:1] + 1e-3)[1]).sum() == 0, \
            "the body keeps its displacements"


# A loose Newton tolerance: the command line's warning.


def test_a_loose_tol_is_warned_as_the_cli_warns(cli, tmp_path):
    """xi spans 2 across a cell: a step tolerance above 1e-3 stops Newton short of the point, and
    points near faces land in the wrong cell (or none). `cgcontact --tol` warns; so does Python."""
    nodes, hexes, _ = coarse_beside_refined()
    mesh = tmp_path / "mesh.vtk"
    write_vtk(mesh, nodes, hexes, np.zeros_like(nodes))
    np.savetxt(tmp_path / "points.csv", nodes[:1], delimiter=",", header="x,y,z", comments="")
    cli_run = subprocess.run([cli, "locate", "--mesh", str(mesh), "--points",
                              str(tmp_path / "points.csv"), "--out", str(tmp_path / "out.csv"),
                              "--tol", "0.1"], capture_output=True, text=True)
    assert cli_run.returncode == 0, cli_run.stderr
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    for precision in ["f64", "f32"]:
        with pytest.warns(UserWarning, match=r"tol 0\.1 is a Newton step tolerance") as caught:
            cgcontact.Locator(body, precision=precision, tol=0.1)
        message = str(caught[0].message)
        assert "above 1e-3" in message and "points near faces" in message, message
        assert f"--{message}" in cli_run.stderr, (message, cli_run.stderr)
        assert caught[0].filename == __file__, caught[0].filename
    # At most 1e-3, or the defaults: no warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for tol in [None, 1e-3, 1e-10]:
            cgcontact.Locator(body, tol=tol)
            cgcontact.Locator(body, precision="f32", tol=tol)
    # A refused tol is an error, not a warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError):
            cgcontact.Locator(body, tol=np.inf)


# Arguments: errors name the argument and what it must be.


@pytest.mark.parametrize(
    "call, error, message",
    [
        # pyo3 named an argument only in TypeErrors: these were OverflowErrors and ValueErrors
        # such as "out of range integral type conversion attempted".
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1), (-1, 2, 2)), ValueError, "counts"),
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1), (2**40, 1, 1)), ValueError, "counts"),
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 2)), ValueError, "counts"),
        (lambda b: cgcontact.Body((0, 0), (1, 1, 1), (2, 2, 2)), ValueError, "origin"),
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1, 1), (2, 2, 2)), ValueError, "spacing"),
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1), (2.5, 2, 2)), TypeError, "counts"),
        (lambda b: cgcontact.Body("xyz", (1, 1, 1), (2, 2, 2)), TypeError, "origin"),
        (lambda b: cgcontact.Locator(b, max_iter=-1), ValueError, "max_iter"),
        (lambda b: cgcontact.Locator(b, max_iter=2**40), ValueError, "max_iter"),
        (lambda b: cgcontact.Locator(b, threads=-1), ValueError, "threads"),
        # A boolean is an int to Python (True is 1), but no count is meant by it: as booleans
        # are refused for coordinates and node numbers.
        (lambda b: cgcontact.Locator(b, max_iter=True), TypeError, "max_iter .* got True"),
        (lambda b: cgcontact.Locator(b, threads=True), TypeError, "threads .* got True"),
        (lambda b: cgcontact.Locator(b, threads=False), TypeError, "threads .* got False"),
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1), (True, 2, 2)), TypeError,
         r"counts .* got \(True, 2, 2\)"),
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1), [2, 2, True]), TypeError, "counts"),
        # numpy's own conversion errors, which named no argument.
        (lambda b: cgcontact.Locator(b).locate([[0, 0, 0], [0, 0]]), ValueError, "points"),
        (lambda b: cgcontact.Locator(b).locate([["a", "b", "c"]]), ValueError, "points"),
        (lambda b: cgcontact.Locator(b).locate(np.array([[{}, 0, 0]], dtype=object)), TypeError,
         "points"),
        (lambda b: cgcontact.Locator(b).locate_owners([[0, 0, 0], [0]]), ValueError, "x"),
        (lambda b: cgcontact.Locator(b).gap([[0, 0, 0], [0]], 1.0), ValueError, "points"),
        (lambda b: b.set_displacements([[0, 0, 0], [0]]), ValueError, "^u "),
        (lambda b: cgcontact.Body.from_hexes([[0, 0, 0], [0]], [[0] * 8]), ValueError, "nodes"),
        (lambda b: cgcontact.Body.from_hexes(np.zeros((8, 3)), [[0] * 8, [0]]), ValueError,
         "hexes"),
        (lambda b: cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 1, 1), [[1], 1]), ValueError,
         "active"),
    ],
)
def test_argument_errors_name_the_argument(call, error, message):
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    with pytest.raises(error, match=message) as caught:
        call(body)
    assert caught.type is error


def test_an_empty_list_is_no_points():
    """`np.array(points_found)` of no points has shape (0,), not (0, 3)."""
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    for empty in [[], np.array([]), ()]:
        cell, xi = locator.locate(empty)
        assert cell.shape == (0,) and xi.shape == (0, 3)
        assert locator.locate_owners(empty) == []
        assert locator.gap(empty, 1.0)["closest"].shape == (0, 3)
    with pytest.raises(ValueError, match=r"shape \(n, 3\), got \(0, 2\)"):
        locator.locate(np.zeros((0, 2)))


def test_values_in_messages_are_short():
    """Display printed 1e300 as 301 digits."""
    nodes, hexes = lattice_hexes()
    body = cgcontact.Body.from_hexes(nodes, hexes)
    u = np.zeros((body.node_count, 3))
    u[4] = [1e300, -1e-300, np.nan]
    for values, row in [(u, 4)]:
        with pytest.raises(ValueError, match=f"row {row}") as caught:
            body.set_displacements(values)
        assert "1e300" in str(caught.value) and len(str(caught.value)) < 200, str(caught.value)
    u[4, 2] = 0.0
    with pytest.raises(ValueError, match="too large") as caught:
        body.set_displacements(u)
    assert "1e300" in str(caught.value) and len(str(caught.value)) < 250, str(caught.value)
    with pytest.raises(ValueError, match="row 0") as caught:
        cgcontact.Locator(body).locate([[1e300, np.inf, 0.5]])
    assert "1e300" in str(caught.value) and len(str(caught.value)) < 200, str(caught.value)


# The stub against the module: every name, parameter and default.

STUB = pathlib.Path(__file__).resolve().parents[1] / "cgcontact.pyi"


def stub_parameters(function):
    """(name, default source or None) of a stub function's parameters, self and cls left out."""
    args = function.args
    positional = args.posonlyargs + args.args
    defaults = [None] * (len(positional) - len(args.defaults)) + list(args.defaults)
    pairs = list(zip(positional, defaults)) + list(zip(args.kwonlyargs, args.kw_defaults))
    return [(a.arg, None if d is None else ast.literal_eval(d)) for a, d in pairs
            if a.arg not in ("self", "cls")]


def runtime_parameters(obj):
    return [(p.name, None if p.default is inspect.Parameter.empty else p.default)
            for p in inspect.signature(obj).parameters.values() if p.name not in ("self", "cls")]


def decorators(function):
    return {d.id if isinstance(d, ast.Name) else getattr(d, "attr", None)
            for d in function.decorator_list}


def test_the_stub_matches_the_module():
    """read_mesh's default showed as `displacement=Ellipsis` at runtime; the stub gave
    `locate_owners` an implementation beside its overloads (mypy: "An implementation for an
    overloaded function is not allowed in a stub file") and `__init__` for classes built by
    `__new__`."""
    tree = ast.parse(STUB.read_text())
    stub = {node.name: node for node in tree.body
            if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
    aliases = [t.id for node in tree.body if isinstance(node, (ast.Assign, ast.AnnAssign))
               for t in (node.targets if isinstance(node, ast.Assign) else [node.target])]
    public = [name for name in stub if not name.startswith("_")]
    assert sorted(public) == sorted(n for n in cgcontact.__all__ if not n.startswith("_"))
    for alias in aliases:
        assert hasattr(cgcontact, alias) or alias.startswith("_"), \
            f"{alias}: a stub-only name must be private"
    all_list = next(node.value for node in tree.body if isinstance(node, ast.Assign)
                    and [t.id for t in node.targets] == ["__all__"])
    assert sorted(ast.literal_eval(all_list)) == sorted(cgcontact.__all__)

    def check(function, runtime, where):
        assert stub_parameters(function) == runtime_parameters(runtime), where

    for name, node in stub.items():
        runtime = getattr(cgcontact, name)
        if isinstance(node, ast.FunctionDef):
            check(node, runtime, name)
            continue
        with pytest.raises(TypeError):
            type("Sub", (runtime,), {})
        assert "final" in decorators(node), f"{name} cannot be subclassed: @final"
        methods = [m for m in node.body if isinstance(m, ast.FunctionDef)]
        assert "__init__" not in [m.name for m in methods], f"{name} is built by __new__"
        overloaded = {m.name for m in methods if "overload" in decorators(m)}
        for m in methods:
            where = f"{name}.{m.name}"
            assert m.name not in overloaded or "overload" in decorators(m), \
                f"{where}: no implementation beside overloads in a stub"
            if "property" in decorators(m):
                assert isinstance(getattr(runtime, m.name), property) or \
                    type(getattr(runtime, m.name)).__name__ == "getset_descriptor", where
            elif m.name == "__new__":
                check(m, runtime, where)
            elif m.name not in overloaded:
                check(m, getattr(runtime, m.name), where)
        documented = {m.name for m in methods} | {"__new__"}
        for attr in vars(runtime):
            if not attr.startswith("_"):
                assert attr in documented, f"{name}.{attr} is missing from the stub"


def test_the_runtime_docstrings_say_what_the_constructors_take():
    """pyo3 drops the doc comment of #[new]: help(Body) never said what `active` takes."""
    assert "cartesian" in cgcontact.__doc__ and len(cgcontact.__doc__) > 200
    assert "active" in cgcontact.Body.__doc__ and "i + nx (j + ny k)" in cgcontact.Body.__doc__
    for word in ["strategy", "precision", "tol", "max_iter", "threads"]:
        assert word in cgcontact.Locator.__doc__, word


def test_out_arrays_in_use_by_another_call_are_named_so():
    """The error said the array shared memory with the points or the other out array: here it
    shares nothing, another thread's call is writing to it."""
    body = cgcontact.Body((0, 0, 0), (1, 1, 1), (20, 20, 20))
    points = np.random.default_rng(5).uniform(0, 20, (100_000, 3))
    out = (np.zeros(len(points), np.int64), np.zeros((len(points), 3)))
    slow = cgcontact.Locator(body, strategy="centroid", threads=1)  # about 1 s here
    busy = threading.Thread(target=slow.locate, args=(points,), kwargs={"out": out})
    busy.start()
    time.sleep(0.3)
    try:
        if not busy.is_alive():
            pytest.skip("the first call ended before the second began")
        with pytest.raises(ValueError, match="another call is writing to it"):
            cgcontact.Locator(body).locate(points.copy(), out=out)
    finally:
        busy.join()
    np.testing.assert_array_equal(out[0], cgcontact.Locator(body).locate(points)[0])


def test_large_batches_on_large_bodies_answer_each_point_in_place():
    """On a body whose displacements leave the caches, the library sorts a large batch by cell:
    the batch is then answered whole and written piece by piece, each answer at its own row,
    as the same points answered in batches too small to sort; and known cells and xi."""
    n_cells = (90, 90, 90)
    body = cgcontact.Body((-1.0, 2.0, 0.0), (0.1, 0.1, 0.1), n_cells)
    rng = np.random.default_rng(5)
    n = 30_000
    ijk = np.column_stack([rng.integers(0, c, n) for c in n_cells])
    xi = rng.uniform(-0.9, 0.9, (n, 3))
    points = (-1.0, 2.0, 0.0) + (ijk + (xi + 1) / 2) * 0.1
    cells = ijk[:, 0] + 90 * (ijk[:, 1] + 90 * ijk[:, 2])
    points[123] = 1e3
    locator = cgcontact.Locator(body, threads=2)
    cell, got = locator.locate(points)
    small = [locator.locate(points[k:k + 1000]) for k in range(0, n, 1000)]
    np.testing.assert_array_equal(cell, np.concatenate([c for c, _ in small]))
    np.testing.assert_array_equal(got, np.concatenate([x for _, x in small]))
    known = np.arange(n) != 123
    np.testing.assert_array_equal(cell[known], cells[known])
    np.testing.assert_allclose(got[known], xi[known], atol=1e-12)
    assert cell[123] == -1 and np.isnan(got[123]).all()
    # Warm, from those answers: the same cells, xi within the Newton tolerance.
    out = (cell.copy(), got.copy())
    warm_cell, warm_xi = locator.relocate(points, out=out)
    np.testing.assert_array_equal(warm_cell, cell)
    np.testing.assert_allclose(warm_xi[known], got[known], atol=1e-12)


def test_whole_batches_relocate_from_any_hint_as_small_ones():
    """A sortable batch answered whole on 3 threads, on a body with inactive cells, warm from bad
    hints (-1, NaN and infinite xi, another point's cell, an active cell far away): the cells of
    batches too small to sort, xi within the Newton tolerance. An inactive lattice cell is no
    previous answer: refused, naming its row, as cgc_relocate refuses it."""
    n_cells = (90, 90, 90)
    active = np.arange(90**3) % 11 != 3
    body = cgcontact.Body((-1.0, 2.0, 0.0), (0.1, 0.1, 0.1), n_cells, active=active)
    rng = np.random.default_rng(8)
    n = 20_000
    points = (-1.0, 2.0, 0.0) + rng.uniform(-0.1, 9.1, (n, 3))
    locator = cgcontact.Locator(body, threads=3)
    small = [locator.locate(points[k:k + 1000]) for k in range(0, n, 1000)]
    cell = np.concatenate([c for c, _ in small])
    xi = np.concatenate([x for _, x in small])
    assert (cell >= 0).sum() > n // 2
    hint_cell, hint_xi = cell.copy(), xi.copy()
    hint_cell[0::5] = -1
    hint_xi[1::5, 0] = np.nan
    hint_xi[2::5, 1] = np.inf
    hint_cell[3::5] = rng.permutation(cell)[3::5]
    hint_cell[4::5] = 0
    inactive = (hint_cell.copy(), hint_xi.copy())
    inactive[0][9] = 3
    with pytest.raises(ValueError, match="row 9 .* lattice cell 3 is not active"):
        locator.relocate(points, out=inactive)
    np.testing.assert_array_equal(inactive[0][10:], hint_cell[10:])
    warm_cell, warm_xi = locator.relocate(points, out=(hint_cell, hint_xi))
    np.testing.assert_array_equal(warm_cell, cell)
    np.testing.assert_allclose(warm_xi, xi, atol=1e-12)


def test_unordered_rows_answer_their_points_as_locate():
    """locate_unordered: row k answers point order[k] bitwise as locate answers it, each point
    once; a batch the library sorts by cell comes cell by cell, one too small to sort in the
    points' order. out= arrays are filled and returned; a NaN point raises, naming its row in
    the points; out arrays sharing memory are refused."""
    body = cgcontact.Body((-1.0, 2.0, 0.0), (0.1, 0.1, 0.1), (90, 90, 90))
    rng = np.random.default_rng(11)
    n = 30_000
    points = (-1.0, 2.0, 0.0) + rng.uniform(-0.1, 9.1, (n, 3))
    locator = cgcontact.Locator(body, threads=2)
    cell, xi = locator.locate(points)
    assert (cell >= 0).sum() > n // 2 and (cell < 0).any()
    for count, sorted_by_cell in ((n, True), (1000, False)):
        order, got_cell, got_xi = locator.locate_unordered(points[:count])
        np.testing.assert_array_equal(np.sort(order), np.arange(count))
        np.testing.assert_array_equal(got_cell, cell[order])
        np.testing.assert_array_equal(got_xi.view(np.int64), xi[order].view(np.int64))
        assert (order == np.arange(count)).all() != sorted_by_cell
    out = (np.full(n, -5, np.int64), np.full(n, -5, np.int64), np.full((n, 3), -5.0))
    got = locator.locate_unordered(points, out=out)
    assert all(a is b for a, b in zip(got, out))
    np.testing.assert_array_equal(out[1], cell[out[0]])
    bad = points.copy()
    bad[7000, 1] = np.nan
    with pytest.raises(ValueError, match="points row 7000 "):
        locator.locate_unordered(bad)
    with pytest.raises(ValueError, match="order array shares memory|cell array shares memory"):
        locator.locate_unordered(points, out=(out[0], out[0], out[2]))
    with pytest.raises(ValueError, match=r"out must be a tuple \(order, cell, xi\)"):
        locator.locate_unordered(points, out=(out[0], out[2]))


def test_kept_buffers_never_leak_a_previous_batch():
    """A locator keeps the answers of its last sorted batch for its next call. Batches that grow
    and shrink, cold, unordered and warm, answer as a new locator answers each: nothing of an
    earlier batch comes back."""
    body = cgcontact.Body((0.0, 0.0, 0.0), (0.1, 0.1, 0.1), (90, 90, 90))
    rng = np.random.default_rng(13)
    kept = cgcontact.Locator(body, threads=2)
    for n in (40_000, 17_000, 60_000, 16_500):
        points = rng.uniform(-0.5, 9.5, (n, 3))
        cell, xi = cgcontact.Locator(body, threads=2).locate(points)
        got_cell, got_xi = kept.locate(points)
        np.testing.assert_array_equal(got_cell, cell)
        np.testing.assert_array_equal(got_xi.view(np.int64), xi.view(np.int64))
        order, got_cell, got_xi = kept.locate_unordered(points[::-1])
        np.testing.assert_array_equal(got_cell, cell[::-1][order])
        warm_cell, warm_xi = kept.relocate(points, out=(cell.copy(), xi.copy()))
        np.testing.assert_array_equal(warm_cell, cell)
        np.testing.assert_allclose(warm_xi, xi, atol=1e-12)


def test_gap_sign_follows_locate_in_each_precision():
    """A point a hair outside a face (1e-9 to 2e-6 of a cell) is held by the f32 locator within
    its inside tolerance: `gap` then says it is inside too. The gap was measured in f64 whatever
    the locator's precision, so `locate` gave a cell beside a positive gap."""
    body = cgcontact.Body(origin=(0, 0, 0), spacing=(0.5, 0.5, 0.5), counts=(2, 2, 2))
    hairs = np.array([1e-9, 1e-7, 5e-7, 1e-6, 2e-6])
    points = np.concatenate([
        np.column_stack([np.full(5, 0.3), np.full(5, 0.4), 1.0 + s * hairs]) for s in (1, -1)
    ] + [np.column_stack([1.0 + hairs, 1.0 + hairs, np.full(5, 0.3)])])
    for precision, least in (("f64", 5), ("f32", 6)):
        locator = cgcontact.Locator(body, precision=precision)
        cell, _ = locator.locate(points)
        gap = locator.gap(points, 0.3)["gap"]
        np.testing.assert_array_equal(cell >= 0, gap <= 0, err_msg=precision)
        assert (cell >= 0).sum() >= least, precision


def test_object_arrays_of_none_or_numpy_dates_are_refused_not_cast():
    """numpy reads None in an object array as NaN, so that a point's error showed a NaN the caller
    never wrote, and a numpy date or time as a count of its unit since 1970: a date became a
    coordinate of 18,262 (days to 2020-01-01) and the point was silently found in no cell."""
    points, _, _ = cell_points()
    locator = cgcontact.Locator(cgcontact.Body(ORIGIN, SPACING, COUNTS))
    for element, shown in [(None, "NoneType None"),
                           (np.datetime64("2020-01-01"), "datetime64"),
                           (np.timedelta64(1, "D"), "timedelta64")]:
        assert_object_element_refused(locator, points, element, shown)


def test_f32_on_cells_too_small_for_f32_is_refused_by_the_locator():
    """The library checks that the f32 kernel resolves the body's cells only when a query builds
    its search: `Locator(body, precision="f32")` on cells of 1e-13 was taken, and every query
    then raised. It is refused where the precision is given, as the C API refuses it."""
    body = cgcontact.Body((0, 0, 0), (1e-13, 1e-13, 1e-13), (2, 2, 2))
    with pytest.raises(ValueError, match="f32 kernel cannot resolve cells of spacing"):
        cgcontact.Locator(body, precision="f32")
    cell, xi = cgcontact.Locator(body).locate([[0.5e-13, 1.5e-13, 0.5e-13]])
    np.testing.assert_array_equal(cell, [2])
    np.testing.assert_allclose(xi, [[0, 0, 0]], atol=1e-9)


def test_active_flags_of_a_large_lattice_take_no_python_object_per_cell():
    """The flags were read as a Python list of one bool per lattice cell: 8 bytes a cell on top
    of the flags' one (1.7 s and 576 MB for a 400^3 lattice of 8 cells, whose flags take 64 MB),
    where a sparse body on a large lattice is meant to cost its few cells."""
    n = 200
    active = np.zeros((n, n, n), dtype=bool)
    active[0, 0, :2] = True
    active[n - 1, n - 1, n - 1] = True
    tracemalloc.start()
    try:
        body = cgcontact.Body((0, 0, 0), (1, 1, 1), (n, n, n), active)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2 * active.nbytes, peak
    assert body.cell_count == 3
    points = np.array([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [n - 0.5] * 3, [0.5, 1.5, 0.5]])
    cell, _ = cgcontact.Locator(body).locate(points)
    np.testing.assert_array_equal(cell, [0, 1, n**3 - 1, -1])


def test_an_out_array_in_use_by_another_call_is_refused_as_input_not_a_panic():
    """numpy's read-only borrow of an input unwrapped a conflict: an array another thread's query
    was writing its answers to, given as points, nodes, displacements or hexes, raised pyo3's
    PanicException (a BaseException, past `except Exception`) with a Rust backtrace."""
    body = cgcontact.Body((0, 0, 0), (1, 1, 1), (20, 20, 20))
    points = np.random.default_rng(5).uniform(0, 20, (100_000, 3))
    cell, xi = np.zeros(len(points), np.int64), np.zeros((len(points), 3))
    slow = cgcontact.Locator(body, strategy="centroid", threads=1)  # about 1 s here
    busy = threading.Thread(target=slow.locate, args=(points,), kwargs={"out": (cell, xi)})
    locator = cgcontact.Locator(body)
    calls = [
        ("points", lambda: locator.locate(xi)),
        ("points", lambda: locator.gap(xi, 0.1)),
        ("x", lambda: locator.locate_owners(xi[7])),  # a view, of shape (3,)
        ("u", lambda: body.set_displacements(xi[:body.node_count])),
        ("nodes", lambda: cgcontact.Body.from_hexes(xi, [list(range(8))])),
        ("hexes", lambda: cgcontact.Body.from_hexes(points, cell.reshape(-1, 8))),
    ]
    busy.start()
    time.sleep(0.3)
    try:
        for what, call in calls:
            if not busy.is_alive():
                pytest.skip("the first call ended before the others began")
            try:
                with pytest.raises(ValueError, match=f"^{what}: another call is writing to this "
                                                     "array"):
                    call()
            except BaseException as e:  # PanicException derives from BaseException only
                pytest.fail(f"{what}: {type(e).__name__}: {e}")
    finally:
        busy.join()
    np.testing.assert_array_equal(cell, cgcontact.Locator(body).locate(points)[0])


ANSWERS_BEYOND_MEMORY = """
import resource
import numpy as np
import cgcontact
locator = cgcontact.Locator(cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 2, 2)))
points = np.full((4_000_000, 3), 0.5)
locator.locate(points[:10])
# Room for what runs now, not for 4 M answers (96 MB of xi, 352 MB of gaps).
size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
resource.setrlimit(resource.RLIMIT_AS, (size + 48 * 2**20, resource.RLIM_INFINITY))
for call in [locator.locate, locator.locate_unordered, lambda p: locator.gap(p, 0.1)]:
    try:
        call(points)
        print("answered")
    except MemoryError:
        print("MemoryError")
print(locator.locate(points[:2])[0])
"""


def test_answers_beyond_memory_are_a_memory_error_not_a_panic_or_an_abort():
    """The answer arrays of `locate` were allocated by rust-numpy, which panics when numpy cannot
    allocate them (a PanicException), and `gap`'s by Rust, which aborts the interpreter."""
    if not pathlib.Path("/proc/self/statm").exists():
        pytest.skip("not Linux: the address space limit is set from /proc/self/statm")
    run = subprocess.run([sys.executable, "-c", ANSWERS_BEYOND_MEMORY], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split("\n")[:3] == ["MemoryError"] * 3, run.stdout + run.stderr[-2000:]
    assert "[0 0]" in run.stdout


OWNERS_BEYOND_MEMORY = """
import resource
import numpy as np
import cgcontact
locator = cgcontact.Locator(cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 2, 2)))
points = np.full((4_000_000, 3), 0.5)
locator.locate_owners(points[:10])
# Room for what runs now, not for a list of owners per point (96 MB of them in Rust alone).
size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
resource.setrlimit(resource.RLIMIT_AS, (size + 48 * 2**20, resource.RLIM_INFINITY))
try:
    locator.locate_owners(points)
    print("answered")
except MemoryError:
    print("MemoryError")
print(locator.locate_owners(points[:1]))
"""


def test_owners_beyond_memory_are_a_memory_error_not_an_abort():
    """`locate_owners` collected a Rust list per point before making Python's: when they did not
    fit, the interpreter aborted."""
    if not pathlib.Path("/proc/self/statm").exists():
        pytest.skip("not Linux: the address space limit is set from /proc/self/statm")
    run = subprocess.run([sys.executable, "-c", OWNERS_BEYOND_MEMORY], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.split("\n")
    assert lines[0] == "MemoryError", run.stdout + run.stderr[-2000:]
    assert lines[1].startswith("[[(0, (0.0, 0.0, 0.0))"), run.stdout


SORTED_BATCH_BEYOND_MEMORY = """
import resource
import numpy as np
import cgcontact
locator = cgcontact.Locator(cgcontact.Body((0, 0, 0), (1, 1, 1), (80, 80, 80)))
points = np.random.default_rng(3).uniform(0, 80, (2_000_000, 3))
out = (np.zeros(len(points), np.int64), np.zeros((len(points), 3)))
unordered = (np.zeros(len(points), np.int64), *out)
locator.locate(points[:20_000])
# Room for what runs now, not for the 56 bytes a point of a sorted batch's kept answers.
size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
resource.setrlimit(resource.RLIMIT_AS, (size + 40 * 2**20, resource.RLIM_INFINITY))
for call in [lambda: locator.locate(points, out=out),
             lambda: locator.relocate(points, out=out),
             lambda: locator.locate_unordered(points, out=unordered)]:
    try:
        call()
        print("answered")
    except MemoryError:
        print("MemoryError")
print(locator.locate(points[:2])[0] >= 0)
"""


def test_a_sorted_batch_beyond_memory_is_a_memory_error_not_an_abort():
    """A batch the library sorts by cell (a large body, points out of order) is answered whole
    into buffers the locator keeps, 56 bytes a point, which Rust allocated: when they did not fit,
    the interpreter aborted."""
    if not pathlib.Path("/proc/self/statm").exists():
        pytest.skip("not Linux: the address space limit is set from /proc/self/statm")
    run = subprocess.run([sys.executable, "-c", SORTED_BATCH_BEYOND_MEMORY],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split("\n")[:3] == ["MemoryError"] * 3, run.stdout + run.stderr[-2000:]
    assert "[ True  True]" in run.stdout


DENSE_FLAGS_BEYOND_MEMORY = """
import resource
import numpy as np
import cgcontact
active = np.ones((200, 200, 200), dtype=bool)
size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
# Room to read the flags (about 72 MB), not for the body's 390 MB.
resource.setrlimit(resource.RLIMIT_AS, (size + 150 * 2**20, resource.RLIM_INFINITY))
try:
    cgcontact.Body((0, 0, 0), (1, 1, 1), (200, 200, 200), active)
    print("built")
except MemoryError as e:
    print("MemoryError", e)
print(cgcontact.Body((0, 0, 0), (1, 1, 1), (2, 2, 2), [1] * 8).cell_count)
"""


def test_active_flags_of_a_body_beyond_memory_are_a_memory_error_not_an_abort():
    """`Body(..., active=None)` probes for its 48 bytes a node before allocating them, but with
    flags given it did not: every cell of a 200^3 lattice active under a 390 MB shortfall aborted
    the interpreter."""
    if not pathlib.Path("/proc/self/statm").exists():
        pytest.skip("not Linux: the address space limit is set from /proc/self/statm")
    run = subprocess.run([sys.executable, "-c", DENSE_FLAGS_BEYOND_MEMORY], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.startswith("MemoryError a body of 8120601 lattice nodes does not fit"), (
        run.stdout + run.stderr[-2000:])
    assert run.stdout.split("\n")[1] == "8"


def test_booleans_and_huge_integers_are_refused_as_numbers_naming_the_argument():
    """`Body((True, 0, 0), ...)` took True as an origin of 1.0, and `Locator(body, tol=True)` and
    `gap(points, True)` took it as 1: booleans were refused for counts and in arrays of points,
    but not there. And `tol=10**400` or `gap(points, 10**400)` raised "OverflowError: int too
    large to convert to float", naming no argument. Both are refused now, naming it."""
    points, _, _ = cell_points()
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    for call, what in [
        (lambda: cgcontact.Body((True, 0, 0), SPACING, COUNTS), "origin"),
        (lambda: cgcontact.Body(ORIGIN, [1, False, 1], COUNTS), "spacing"),
        (lambda: cgcontact.Locator(body, tol=True), "tol"),
        (lambda: cgcontact.Locator(body).gap(points, True), "dist"),
    ]:
        with pytest.raises(TypeError, match=f"{what} must be .*, got .*(True|False)"):
            call()
    for call, what in [
        (lambda: cgcontact.Locator(body, tol=10**400), "tol"),
        (lambda: cgcontact.Locator(body).gap(points, 10**400), "dist"),
    ]:
        with pytest.raises(ValueError, match=f"{what} must be a number, got 1000"):
            call()
    # Numbers of any real kind still are numbers.
    cgcontact.Body(np.array(ORIGIN), tuple(np.float32(h) for h in SPACING), COUNTS)
    cgcontact.Locator(body, tol=np.float64(1e-9)).gap(points, np.float32(0.5))
    cgcontact.Locator(body).gap(points, 2)


def test_out_arrays_sharing_memory_through_other_objects_are_refused():
    """rust-numpy's borrow flags see views of one base object only: an xi array viewing the
    points' bytearray through a memoryview of it passed them, and answers written over points not
    yet read gave 2795 wrong cells of 5000, without a word (and overwrote the points). The bytes
    the arrays span are compared now, for the points and every pair of out arrays."""
    locator = cgcontact.Locator(cgcontact.Body((-2, -2, -2), (1, 1, 1), (8, 8, 8)))
    n, shift = 5000, 700
    memory = bytearray((n + shift) * 24)
    points = np.frombuffer(memory, np.float64).reshape(-1, 3)[:n]
    points[:] = 0.05 + np.random.default_rng(2).random((n, 3)) * 3.9
    given = points.copy()
    xi = np.frombuffer(memoryview(memory), np.float64).reshape(-1, 3)[shift:shift + n]
    cells = np.zeros(n, np.int64)
    refusals = [
        lambda: locator.locate(points, out=(cells, xi)),
        lambda: locator.relocate(points, out=(cells, xi)),
        lambda: locator.locate_unordered(points, out=(np.zeros(n, np.int64), cells, xi)),
    ]
    for call in refusals:
        with pytest.raises(ValueError, match="out: the xi array shares memory with the points"):
            call()
    np.testing.assert_array_equal(points, given)
    # Out arrays over one buffer, each through a memoryview of its own.
    buffer = bytearray(8 * 4 * n)
    ints = [np.frombuffer(memoryview(buffer), np.int64) for _ in range(2)]
    floats = np.frombuffer(memoryview(buffer), np.float64)
    with pytest.raises(ValueError, match="out: the xi array shares memory with the cell array"):
        locator.locate(given, out=(ints[0][:n], floats[n // 2:n // 2 + 3 * n].reshape(n, 3)))
    with pytest.raises(ValueError, match="out: the cell array shares memory with the order array"):
        locator.locate_unordered(given, out=(ints[0][:n], ints[1][1:n + 1], np.zeros((n, 3))))
    # Side by side in one buffer, they share no byte and are written.
    expected_cells, expected_xi = locator.locate(given)
    got_cells, got_xi = locator.locate(given, out=(ints[0][:n], floats[n:].reshape(n, 3)))
    np.testing.assert_array_equal(got_cells, expected_cells)
    np.testing.assert_array_equal(got_xi, expected_xi)


def test_numpy_booleans_are_refused_as_numbers():
    """Python's `True` was refused as an origin, a spacing, `tol` or `dist`, but `numpy.True_`,
    a boolean array and an object array holding `numpy.True_` were taken as 1.0."""
    points, _, _ = cell_points()
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    for call, what in [
        (lambda: cgcontact.Body((np.True_, 0, 0), SPACING, COUNTS), "origin"),
        (lambda: cgcontact.Body(np.array([True, False, False]), SPACING, COUNTS), "origin"),
        (lambda: cgcontact.Body(ORIGIN, np.ones(3, bool), COUNTS), "spacing"),
        (lambda: cgcontact.Body(ORIGIN, np.array([1, np.True_, 1], object), COUNTS), "spacing"),
        (lambda: cgcontact.Locator(body, tol=np.True_), "tol"),
        (lambda: cgcontact.Locator(body, tol=np.array(True)), "tol"),
        (lambda: cgcontact.Locator(body).gap(points, np.True_), "dist"),
    ]:
        with pytest.raises(TypeError, match=f"{what} must be .*, got "):
            call()
    # Numbers of numpy's real kinds still are numbers.
    cgcontact.Body(np.array(ORIGIN), np.array(SPACING, np.float32), np.array(COUNTS))
    cgcontact.Locator(body, tol=np.float64(1e-9), max_iter=np.int64(30)).gap(points, np.int8(1))


def test_ints_beyond_float64_in_arrays_are_a_value_error_naming_the_argument():
    """A Python int beyond float64 in points, u or nodes (or beyond int64 in hexes) raised
    "OverflowError: int too large to convert to float", naming no argument: a ValueError naming
    it now, as for any value out of range."""
    body = cgcontact.Body(ORIGIN, SPACING, COUNTS)
    locator = cgcontact.Locator(body)
    huge = [[10**400, 0, 0]]
    nodes, hexes = lattice_hexes()
    for call, what in [
        (lambda: locator.locate(huge), "points"),
        (lambda: locator.gap(huge, 1.0), "points"),
        (lambda: locator.locate_owners(huge[0]), "x"),
        (lambda: body.set_displacements(huge * body.node_count), "u"),
        (lambda: cgcontact.Body.from_hexes(huge + nodes[1:].tolist(), hexes), "nodes"),
        (lambda: cgcontact.Body.from_hexes(nodes, [[10**400] + [0] * 7]), "hexes"),
    ]:
        with pytest.raises(ValueError, match=f"^{what} cannot be read as a numeric array: .*too"):
            call()


def test_complex_and_time_flags_are_refused_not_cast():
    """`active` went through numpy's cast to booleans, and a flag was any value equal to its
    cast: `numpy.ones(8, complex)` and `numpy.ones(8, "timedelta64[s]")` made 8 active cells, where
    points refuse such arrays. `active` refuses what points refuse, but booleans."""
    lattice = ((0, 0, 0), (1, 1, 1), (2, 2, 2))
    for flags, shown in [
        (np.ones(8, complex), "complex128"),
        (np.array([1 + 0j] * 8, object), "object holding complex"),
        (np.ones(8, "timedelta64[s]"), "timedelta64"),
        (np.ones(8, "datetime64[s]"), "datetime64"),
        (np.array(["1"] * 8), "<U1"),
    ]:
        with pytest.raises(ValueError, match=f"active must hold booleans, or 0s and 1s, got dtype "
                                             f"{shown}"):
            cgcontact.Body(*lattice, active=flags)
    for flags in [np.ones(8, bool), np.ones(8), np.ones(8, np.uint8), [True] * 8,
                  np.array([True] * 8, object), np.array([1] * 8, object)]:
        assert cgcontact.Body(*lattice, active=flags).cell_count == 8


BODIES_AT_THE_EDGE_OF_MEMORY = """
import json, os, resource, sys
import numpy as np
import cgcontact
mode, n = sys.argv[1], 40
nodes_count = (n + 1) ** 3
if mode == "hexes":
    k, j, i = np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij")
    nodes = np.column_stack([i.ravel(), j.ravel(), k.ravel()]).astype(float)
    k, j, i = (a.ravel() for a in np.meshgrid(*[np.arange(n)] * 3, indexing="ij"))
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    hexes = np.column_stack([i + a + (n + 1) * (j + b + (n + 1) * (k + c)) for a, b, c in corners])
outcomes = []
# Room for 24 to 64 bytes a lattice node, or 24 to 320 a mesh node, above what the process holds:
# a child process each, forked before any query starts rayon's threads.
for room in range(96, 256, 2) if mode == "lattice" else range(24, 320, 8):
    pid = os.fork()
    if pid == 0:
        size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
        limit = size + room * nodes_count // (4 if mode == "lattice" else 1)
        resource.setrlimit(resource.RLIMIT_AS, (limit, resource.RLIM_INFINITY))
        try:
            if mode == "lattice":
                cgcontact.Body((0, 0, 0), (1, 1, 1), (n, n, n))
            else:
                cgcontact.Body.from_hexes(nodes, hexes)
        except MemoryError:
            os._exit(3)
        except BaseException:
            os._exit(4)
        os._exit(0)
    status = os.waitpid(pid, 0)[1]
    outcomes.append(-os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status))
print(json.dumps(outcomes))
"""


@pytest.mark.parametrize("mode", ["lattice", "hexes"])
def test_a_body_at_the_edge_of_memory_is_a_memory_error_not_an_abort(mode):
    """`Body(origin, spacing, counts)` probed for 48 bytes a node, but its build takes more (4
    bytes a cell while it builds, and freed memory the allocator may not reuse): with a little
    less room than that, the interpreter aborted ("memory allocation of 1654104 bytes failed").
    `Body.from_hexes` had no check at all. Built with room from too little to enough, each body
    is built or raises MemoryError; none is killed by a signal."""
    if not hasattr(os, "fork") or not pathlib.Path("/proc/self/statm").exists():
        pytest.skip("not Linux: the address space limit is set from /proc/self/statm")
    run = subprocess.run([sys.executable, "-c", BODIES_AT_THE_EDGE_OF_MEMORY, mode],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    outcomes = json.loads(run.stdout)
    assert set(outcomes) <= {0, 3}, (outcomes, run.stderr[-2000:])
    # The room given spans both outcomes.
    assert outcomes[0] == 3 and outcomes[-1] == 0, outcomes
