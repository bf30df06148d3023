"""An audit of `cgcontact locate` on adaptive meshes it has never seen, written by VTK itself.

Each seed makes a random refinement of a small base lattice (1 to 5 levels, jumps of any number of
levels between neighbours, holes), its nodes and cells shuffled, hanging-node displacements set to
their coarse leaf's interpolation (computed here), a rigid shift of up to 4 cells on some seeds,
and offsets, scales and anisotropy from 1e-9 to 1e6; VTK's own writers write it (legacy 4.2 or
5.1, XML; ASCII or binary). 400 points are made from known (leaf, xi), a third on nodes, edges and
faces. Every answer of `cgcontact locate --all-owners` is checked here, independently of
cgcontact: the known leaf is among the owners, each owner's xi maps back to the point (trilinear
map of the file's values, to 1e-8 of a cell plus the coordinates' rounding) and lies in
[-1, 1]^3, the known leaf's xi is the known one, and, in binary files, the owners are exactly the
leaves whose undeformed closed box holds the point, or misses it by no more than the rounding
allowance of docs/numerics.md (a point a few ulps off a face far from the origin). With AUDIT_PY=1 the Python module (built
with maturin) answers the same points bitwise as the CLI (one owner, every owner, and the gap
columns); with AUDIT_MPI=path/to/cgcontact-mpi,
`mpirun` on 2 and 3 ranks (slabs, morton, random partitions) writes the CLI's results file byte for
byte, with and without --gap; with AUDIT_STRATEGIES=1, `--strategy rtree` and `brute` list the
same owners with the same xi (to 1e-9); with AUDIT_CAPI=path/to/libcgcontact_capi.so, the C API
(the Octave MEX's path) answers `locate` and the gap columns bit for bit as the CLI (binary files);
with AUDIT_PVTU=1, the same mesh dealt into 2 to 4 pieces of a parallel file (.pvtu), with a ghost
layer flagged in vtkGhostType on half the seeds, gives every owner of every point bit for bit as
the serial file (XML seeds), and never names a ghost copy (with AUDIT_MPI too, mpirun on 3 ranks
writes the CLI's results file of the parallel file, with --gap, byte for byte).

Usage: CGCONTACT_BIN=target/release/cgcontact python3 tools/audit_adaptive_vtk.py FIRST END
(seeds FIRST..END; needs the `vtk` and `numpy` packages; AUDIT_L=0 makes uniform meshes).
A seed whose mesh cgcontact refuses is reported with the message: VTK's legacy ASCII writer keeps
11 significant digits, which cannot place cells of 1e-4 near 2e6 (seeds 52 and 80 of 0..150; the
message then says how far the digits are off, against the smallest edge).
"""
import csv, itertools, json, os, random, subprocess, sys
import numpy as np
import vtk
from vtk.util import numpy_support as ns

BIN = os.environ.get("CGCONTACT_BIN", "cgcontact")
WORK = os.environ.get("AUDIT_DIR") or __import__("tempfile").mkdtemp(prefix="cgcontact-audit-")
EPS = np.finfo(float).eps
CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]


def build(rng, n, L, p_refine, p_hole):
    leaves = []  # (level, i, j, k) in level units

    def split(l, i, j, k):
        if l < L and rng.random() < p_refine * (0.85 ** l):
            for a, b, c in itertools.product((0, 1), repeat=3):
                split(l + 1, 2 * i + a, 2 * j + b, 2 * k + c)
        elif rng.random() >= p_hole:
            leaves.append((l, i, j, k))

    for i in range(n[0]):
        for j in range(n[1]):
            for k in range(n[2]):
                split(0, i, j, k)
    return leaves


def corner_keys(leaf, L):
    l, i, j, k = leaf
    s = 1 << (L - l)
    return [((i + a) * s, (j + b) * s, (k + c) * s) for a, b, c in CORNERS]


def trilinear(xi):
    x, y, z = xi
    return np.array([(1 + (2 * a - 1) * x) * (1 + (2 * b - 1) * y) * (1 + (2 * c - 1) * z) / 8 for a, b, c in CORNERS])


def scene(seed, n, L, origin, h, p_refine=0.5, p_hole=0.05, amp=0.3, shift=(0.0, 0.0, 0.0)):
    rng = random.Random(seed)
    leaves = build(rng, n, L, p_refine, p_hole)
    keys = {}
    for leaf in leaves:
        for key in corner_keys(leaf, L):
            keys.setdefault(key, len(keys))
    key_list = list(keys)
    # The coarsest leaf a node hangs on: a leaf holding the node in its closed box without having
    # it as a corner. Per level, the leaves whose closed box can hold the node are those at
    # floor(key / s), and one lower on each axis where the node lies on the level's lattice.
    S = 1 << L
    leaf_set = set(leaves)
    hang = {}
    for key in key_list:
        for l in range(L + 1):
            s = 1 << (L - l)
            if all(key[a] % s == 0 for a in range(3)):
                continue  # a corner of every level-l leaf holding it
            axes = [(key[a] // s - 1, key[a] // s) if key[a] % s == 0 else (key[a] // s,) for a in range(3)]
            found = next((cand for cand in ((l, i, j, k) for i, j, k in itertools.product(*axes)) if cand in leaf_set), None)
            if found is not None:
                hang[key] = found
                break
    # Independent nodes: a smooth field in finest-lattice units, scaled by the finest spacing.
    hf = np.array(h) / S
    phase = [rng.uniform(0, 6.28) for _ in range(9)]
    def field(key):
        x = np.array(key, float) / S
        return hf * amp * np.array([
            np.sin(0.7 * x[1] + phase[0]) + 0.5 * np.cos(0.9 * x[2] + phase[1]),
            np.sin(0.8 * x[2] + phase[2]) + 0.5 * np.cos(0.6 * x[0] + phase[3]),
            np.sin(0.5 * x[0] + phase[4]) + 0.5 * np.cos(1.1 * x[1] + phase[5]),
        ]) + np.array(shift) * np.array(h)
    u = {key: field(key) for key in key_list if key not in hang}
    # Hanging nodes from the coarse leaf's corners, coarsest first (a corner may hang itself).
    pending = sorted(hang, key=lambda key: hang[key][0])
    for _ in range(L + 2):
        left = []
        for key in pending:
            leaf = hang[key]
            l, i, j, k = leaf
            s = 1 << (L - l)
            cks = corner_keys(leaf, L)
            if all(c in u for c in cks):
                xi = [2 * (key[a] - (i, j, k)[a] * s) / s - 1 for a in range(3)]
                N = trilinear(xi)
                u[key] = sum(N[c] * u[cks[c]] for c in range(8))
            else:
                left.append(key)
        pending = left
    assert not pending
    X = {key: np.array(origin) + np.array(key, float) * hf for key in key_list}
    return leaves, key_list, X, u, hang


def write(path, leaves, key_list, X, u, L, rng, legacy=False, binary=True):
    perm = list(range(len(key_list)))
    rng.shuffle(perm)  # file node of key index q is perm[q]
    pts = np.zeros((len(key_list), 3))
    disp = np.zeros((len(key_list), 3))
    for q, key in enumerate(key_list):
        pts[perm[q]] = X[key]
        disp[perm[q]] = u[key]
    index = {key: perm[q] for q, key in enumerate(key_list)}
    order = list(range(len(leaves)))
    rng.shuffle(order)  # file cell c is leaves[order[c]]
    g = vtk.vtkUnstructuredGrid()
    vp = vtk.vtkPoints()
    vp.SetDataTypeToDouble()
    vp.SetData(ns.numpy_to_vtk(pts, deep=True))
    g.SetPoints(vp)
    for c in order:
        ids = vtk.vtkIdList()
        for key in corner_keys(leaves[c], L):
            ids.InsertNextId(index[key])
        g.InsertNextCell(vtk.VTK_HEXAHEDRON, ids)
    arr = ns.numpy_to_vtk(disp, deep=True)
    arr.SetName("displacement")
    g.GetPointData().AddArray(arr)
    if legacy:
        w = vtk.vtkUnstructuredGridWriter()
        w.SetFileVersion(51 if rng.random() < 0.5 else 42)
        if binary:
            w.SetFileTypeToBinary()
    else:
        w = vtk.vtkXMLUnstructuredGridWriter()
        if not binary:
            w.SetDataModeToAscii()
        elif rng.random() < 0.5:
            w.SetDataModeToAppended()
    w.SetFileName(path)
    w.SetInputData(g)
    assert w.Write() == 1
    # What the file holds (ASCII rounds to 11 digits): the truth the checks use.
    r = vtk.vtkUnstructuredGridReader() if legacy else vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    if legacy:
        r.ReadAllFieldsOn()
    r.Update()
    back = r.GetOutput()
    fp = ns.vtk_to_numpy(back.GetPoints().GetData()).astype(float)
    fu = ns.vtk_to_numpy(back.GetPointData().GetArray("displacement")).astype(float)
    for key in key_list:
        X[key] = fp[index[key]]
        u[key] = fu[index[key]]
    hexes = np.array([[index[key] for key in corner_keys(leaves[c], L)] for c in order], dtype=np.int64)
    return order, (fp, fu, hexes)


def write_pvtu(wd, fp, fu, hexes, rng):
    """The serial file's cells (`hexes` into nodes `fp`, displacements `fu`) as a parallel file of
    2 to 4 pieces, its cells dealt at random, with a ghost layer on half the seeds. Returns its
    path, the serial cell of each of its cells (VTK's numbering: across the pieces, in order) and
    the set of its ghost copies."""
    k = rng.randint(2, 4)
    part = [rng.randrange(k) for _ in range(len(hexes))]
    ghosts_on = rng.random() < 0.5
    cells_of_node = {}
    for c, h in enumerate(hexes):
        for node in h:
            cells_of_node.setdefault(int(node), set()).add(c)
    piece_cells, ghost_cells, names = [], set(), []
    for p in range(k):
        own = [c for c in range(len(hexes)) if part[c] == p]
        ghosts = sorted({d for c in own for node in hexes[c] for d in cells_of_node[int(node)] if part[d] != p}) if ghosts_on else []
        cells = own + ghosts
        rng.shuffle(cells)
        nodes = sorted({int(node) for c in cells for node in hexes[c]})
        rng.shuffle(nodes)
        local = {node: i for i, node in enumerate(nodes)}
        g = vtk.vtkUnstructuredGrid()
        vp = vtk.vtkPoints()
        vp.SetDataTypeToDouble()
        vp.SetData(ns.numpy_to_vtk(np.ascontiguousarray(fp[nodes]) if nodes else np.zeros((0, 3)), deep=True))
        g.SetPoints(vp)
        flags = vtk.vtkUnsignedCharArray()
        flags.SetName("vtkGhostType")
        ghost_set = set(ghosts)
        for c in cells:
            ids = vtk.vtkIdList()
            for node in hexes[c]:
                ids.InsertNextId(local[int(node)])
            g.InsertNextCell(vtk.VTK_HEXAHEDRON, ids)
            flags.InsertNextValue(1 if c in ghost_set else 0)
            if c in ghost_set:
                ghost_cells.add(len(piece_cells))
            piece_cells.append(c)
        arr = ns.numpy_to_vtk(np.ascontiguousarray(fu[nodes]) if nodes else np.zeros((0, 3)), deep=True)
        arr.SetName("displacement")
        g.GetPointData().AddArray(arr)
        if ghosts_on:
            g.GetCellData().AddArray(flags)
        w = vtk.vtkXMLUnstructuredGridWriter()
        mode = rng.random()
        if mode < 0.2:
            w.SetDataModeToAscii()
        elif mode < 0.6:
            w.SetDataModeToAppended()
        name = f"piece_{p}.vtu"
        w.SetFileName(os.path.join(wd, name))
        w.SetInputData(g)
        assert w.Write() == 1
        names.append(name)
    path = os.path.join(wd, "mesh.pvtu")
    with open(path, "w") as f:
        f.write('<?xml version="1.0"?>\n<VTKFile type="PUnstructuredGrid" version="0.1" byte_order="LittleEndian">\n')
        f.write(f'  <PUnstructuredGrid GhostLevel="{int(ghosts_on)}">\n')
        f.write('    <PPointData><PDataArray type="Float64" Name="displacement" NumberOfComponents="3"/></PPointData>\n')
        if ghosts_on:
            f.write('    <PCellData><PDataArray type="UInt8" Name="vtkGhostType"/></PCellData>\n')
        f.write('    <PPoints><PDataArray type="Float64" Name="Points" NumberOfComponents="3"/></PPoints>\n')
        for name in names:
            f.write(f'    <Piece Source="{name}"/>\n')
        f.write("  </PUnstructuredGrid>\n</VTKFile>\n")
    return path, k, piece_cells, ghost_cells


def points_for(leaves, L, X, u, rng, count):
    pts, known = [], []
    specials = [-1.0, 0.0, 1.0]
    for _ in range(count):
        li = rng.randrange(len(leaves))
        leaf = leaves[li]
        r = rng.random()
        if r < 0.35:
            xi = [rng.choice(specials) for _ in range(3)]
        elif r < 0.55:
            xi = [rng.choice(specials) if rng.random() < 0.5 else rng.uniform(-1, 1) for _ in range(3)]
        elif r < 0.6:
            xi = [rng.choice([-0.5, 0.5, -0.75, 0.25]) for _ in range(3)]
        else:
            xi = [rng.uniform(-1, 1) for _ in range(3)]
        cks = corner_keys(leaf, L)
        N = trilinear(xi)
        x = sum(N[c] * (X[cks[c]] + u[cks[c]]) for c in range(8))
        pts.append(x)
        l, i, j, k = leaf
        sz = 1 << (L - l)
        pos8 = tuple((lo * sz) * 8 + (v + 1) * 4 * sz for lo, v in zip((i, j, k), xi))
        known.append((li, xi, pos8))
    return np.array(pts), known


def run(workdir, mesh, pts, extra=()):
    pfile = os.path.join(workdir, "points.csv")
    with open(pfile, "w") as f:
        f.write("x,y,z\n")
        for p in pts:
            f.write("%r,%r,%r\n" % tuple(float(v) for v in p))
    out = os.path.join(workdir, "out.csv")
    r = subprocess.run([BIN, "locate", "--mesh", mesh, "--points", pfile, "--out", out, "--json", *extra], capture_output=True, text=True)
    return r, out


def check(seed, n, L, origin, h, count=400, legacy=False, binary=True, **kw):
    rng = random.Random(seed * 7 + 1)
    leaves, key_list, X, u, hang = scene(seed, n, L, origin, h, **kw)
    if not leaves:
        print("skip", f"seed={seed}: every cell a hole")
        return True
    wd = os.path.join(WORK, f"w{seed}")
    os.makedirs(wd, exist_ok=True)
    mesh = os.path.join(wd, "mesh.vtk" if legacy else "mesh.vtu")
    exact = {key: (X[key].copy(), u[key].copy()) for key in key_list}
    order, (fp, fu, hexes) = write(mesh, leaves, key_list, X, u, L, rng, legacy, binary)
    # How far the file's prints moved the nodes (0 in binary files), per axis: a hanging node
    # then lies off its coarse face by up to that, and the locator's allowance takes the seam
    # (docs/formats.md, "The mesh is where the file has it"), so a point on the seam may be
    # given the leaf across it, its xi clamped, up to twice that away; the leaf's shear carries
    # that onto the other axes, so the largest axis's bound is taken on every axis.
    seam = 2 * np.max([np.abs(X[k] - exact[k][0]) + np.abs(u[k] - exact[k][1]) for k in key_list])
    file_of_leaf = {li: c for c, li in enumerate(order)}
    file_of_key = {leaves[li]: c for c, li in enumerate(order)}
    pts, known = points_for(leaves, L, X, u, rng, count)
    r, out = run(wd, mesh, pts, ["--all-owners"])
    tag = f"seed={seed} n={n} L={L} origin={origin} h={h} leaves={len(leaves)} hanging={len(hang)} legacy={legacy} binary={binary} {kw}"
    if r.returncode != 0:
        print("FAIL rc", r.returncode, tag, r.stderr[-600:])
        return False
    rows = {}
    with open(out) as f:
        for row in csv.DictReader(f):
            rows.setdefault(int(row["point"]), []).append(row)
    hf = np.array(h) / (1 << L)
    scale = max(abs(np.array(origin)).max(), (np.array(n) * np.array(h)).max())
    umax = np.abs(np.array(list(u.values()))).max(axis=0)
    ok = True
    bad = 0
    for p, (li, xi, pos8) in enumerate(known):
        got = rows.get(p, [])
        cells = [int(g["cell"]) for g in got]
        want = file_of_leaf[li]
        if want not in cells:
            bad += 1
            if bad <= 5:
                print("MISS", tag, "point", p, "leaf", leaves[li], "xi", xi, "file cell", want, "got", cells)
            ok = False
            continue
        if binary:
            # Per level, the leaves whose closed box can hold the point: at floor(q / size), and
            # one lower on each axis where the point lies on the level's lattice.
            expect = set()
            for l in range(L + 1):
                sz = (1 << (L - l)) * 8
                axes = [(q // sz - 1, q // sz) if q % sz == 0 else (q // sz,) for q in pos8]
                for i, j, k in itertools.product(*axes):
                    c2 = file_of_key.get((l, i, j, k))
                    if c2 is not None:
                        expect.add(c2)
        else:
            expect = set(cells)  # ASCII rounds: owners on faces are not checked
        # An owner whose closed box the point misses by no more than the rounding the data
        # carries (docs/numerics.md, "Inside": L_j = 4 eps max(|x_j|, |origin_j|) + 4 eps u_max_j,
        # twice over for the deformed leaf's Jacobian) is the locator's documented allowance.
        x = pts[p]
        allowance = 2 * (4 * EPS * np.maximum(np.abs(x), np.abs(np.array(origin))) + 4 * EPS * umax)
        for c2 in set(cells) - expect:
            l, i, j, k = leaves[order[c2]]
            sz = (1 << (L - l)) * 8
            outside = [max(0, lo * sz - q, q - (lo + 1) * sz) / 8 * hf[a]
                       for a, (lo, q) in enumerate(zip((i, j, k), pos8))]
            if all(d <= allowance[a] for a, d in enumerate(outside)):
                expect.add(c2)
        if set(cells) != expect:
            bad += 1
            if bad <= 5:
                print("OWNERS", tag, "point", p, "leaf", leaves[li], "xi", xi, "expected", sorted(expect), "got", sorted(cells))
            ok = False
        for g in got:
            c = int(g["cell"])
            gxi = [float(g["xi"]), float(g["eta"]), float(g["zeta"])]
            leaf = leaves[order[c]]
            cks = corner_keys(leaf, L)
            N = trilinear(gxi)
            x = sum(N[k] * (X[cks[k]] + u[cks[k]]) for k in range(8))
            err = np.maximum(np.abs(x - pts[p]) - seam, 0) / hf
            lim = 1e-8 + 64 * np.finfo(float).eps * scale / hf.min()
            if err.max() > lim or max(abs(v) for v in gxi) > 1 + 1e-9:
                bad += 1
                if bad <= 5:
                    print("BAD", tag, "point", p, "cell", c, "xi", gxi, "err/h", err.max(), "lim", lim)
                ok = False
            if c == want:
                e = max(abs(a - b) for a, b in zip(gxi, xi))
                if e > 1e-9 + lim:
                    bad += 1
                    if bad <= 5:
                        print("XI", tag, "point", p, "xi", gxi, "known", xi, "err", e)
                    ok = False
    summary = json.loads(r.stdout) if r.stdout.strip().startswith("{") else {}
    # The Python binding on the same arrays: bitwise the CLI's one-owner answers.
    if binary and os.environ.get("AUDIT_PY"):
        import cgcontact
        r1, out1 = run(wd, mesh, pts)
        cli = {}
        with open(out1) as f:
            for row in csv.DictReader(f):
                cli[int(row["point"])] = (int(row["cell"]), [float(row[k]) for k in ("xi", "eta", "zeta")])
        body = cgcontact.Body.from_hexes(fp, hexes)
        body.set_displacements(fu)
        cell, xi = cgcontact.Locator(body).locate(np.ascontiguousarray(pts))
        for p in range(len(pts)):
            c, x = cli[p]
            if c != cell[p] or any(np.float64(a).tobytes() != np.float64(b).tobytes() for a, b in zip(x, xi[p])):
                bad += 1
                ok = False
                if bad <= 5:
                    print("PY", tag, "point", p, "cli", c, x, "py", cell[p], xi[p].tolist())
        bits = lambda v: np.float64(v).tobytes()
        locator = cgcontact.Locator(body)
        # Every owner: `--all-owners`'s rows.
        for p, owners in enumerate(locator.locate_owners(np.ascontiguousarray(pts))):
            want = [(int(g["cell"]), [float(g[k]) for k in ("xi", "eta", "zeta")]) for g in rows.get(p, []) if int(g["cell"]) >= 0]
            if len(owners) != len(want) or any(c != wc or any(bits(a) != bits(b) for a, b in zip(x, wx)) for (c, x), (wc, wx) in zip(owners, want)):
                bad += 1
                ok = False
                if bad <= 5:
                    print("PY OWNERS", tag, "point", p, "cli", want, "py", owners)
        # The gap columns of `--gap D`: bitwise, empty where Python has NaN and -1.
        dist = float(max(h))
        rg, outg = run(wd, mesh, pts, ["--gap", repr(dist)])
        gaps = locator.gap(np.ascontiguousarray(pts), dist)
        with open(outg) as f:
            for row in csv.DictReader(f):
                p = int(row["point"])
                if row["gap"] == "":
                    same = np.isnan(gaps["gap"][p]) and gaps["face_cell"][p] == -1
                else:
                    got = [gaps["gap"][p], *gaps["closest"][p], *gaps["normal"][p]]
                    want = [float(row[k]) for k in ("gap", "cx", "cy", "cz", "nx", "ny", "nz")]
                    same = all(bits(a) == bits(b) for a, b in zip(got, want)) and \
                        (int(row["face_cell"]), int(row["face"])) == (gaps["face_cell"][p], gaps["face"][p])
                if not same:
                    bad += 1
                    ok = False
                    if bad <= 5:
                        print("PY GAP", tag, "point", p, "cli", dict(row), "py", {k: v[p] for k, v in gaps.items()})
    # The C API (the Octave MEX's path) on the same arrays: bitwise the CLI's one-owner answers
    # and gap columns (binary files, as for Python).
    if binary and os.environ.get("AUDIT_CAPI"):
        import ctypes
        lib = ctypes.CDLL(os.environ["AUDIT_CAPI"])
        dp, i64p = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int64)
        arr = lambda a, t: np.ascontiguousarray(a, dtype=t)
        ptr = lambda a, t: a.ctypes.data_as(t)
        nodes, cells, disp, q = arr(fp, np.float64), arr(hexes, np.int64), arr(fu, np.float64), arr(pts, np.float64)
        body, loc = ctypes.c_void_p(), ctypes.c_void_p()
        lib.cgc_last_error.restype = ctypes.c_char_p
        calls = [lib.cgc_body_from_mesh(ptr(nodes, dp), ctypes.c_size_t(len(nodes)), ptr(cells, i64p), ctypes.c_size_t(len(cells)), ctypes.c_int64(0), ctypes.byref(body))]
        calls.append(lib.cgc_body_set_displacements(body, ptr(disp, dp), ctypes.c_size_t(len(disp)), ctypes.c_uint32(0)))
        calls.append(lib.cgc_locator_new(body, None, ctypes.byref(loc)))
        n = len(q)
        ccell, cxi = np.zeros(n, np.int64), np.zeros((n, 3))
        calls.append(lib.cgc_locate(loc, ptr(q, dp), ctypes.c_size_t(n), ptr(ccell, i64p), ptr(cxi, dp), None))
        dist = float(max(h))
        g, cl, nm = np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3))
        fc, fa = np.zeros(n, np.int64), np.zeros(n, np.int32)
        calls.append(lib.cgc_gap(loc, ptr(q, dp), ctypes.c_size_t(n), ctypes.c_double(dist), ptr(g, dp), ptr(cl, dp), ptr(nm, dp),
                                 ptr(fc, i64p), fa.ctypes.data_as(ctypes.POINTER(ctypes.c_int32))))
        if any(calls):
            bad += 1
            ok = False
            print("CAPI", tag, "calls returned", calls, lib.cgc_last_error())
        else:
            bits = lambda v: np.float64(v).tobytes()
            r1, out1 = run(wd, mesh, pts)
            rg, outg = run(wd, mesh, pts, ["--gap", repr(dist)])
            with open(out1) as f1, open(outg) as fg:
                for row, grow in zip(csv.DictReader(f1), csv.DictReader(fg)):
                    p = int(row["point"])
                    same = int(row["cell"]) == ccell[p] and all(bits(float(row[k])) == bits(v) for k, v in zip(("xi", "eta", "zeta"), cxi[p]))
                    if grow["gap"] == "":
                        same &= bool(np.isnan(g[p])) and fc[p] == -1
                    else:
                        want = [float(grow[k]) for k in ("gap", "cx", "cy", "cz", "nx", "ny", "nz")]
                        same &= all(bits(a) == bits(b) for a, b in zip([g[p], *cl[p], *nm[p]], want))
                        same &= (int(grow["face_cell"]), int(grow["face"])) == (fc[p], fa[p])
                    if not same:
                        bad += 1
                        ok = False
                        if bad <= 5:
                            print("CAPI", tag, "point", p, "cli", dict(row), dict(grow), "capi", ccell[p], cxi[p], g[p], fc[p], fa[p])
        lib.cgc_locator_free(loc)
        lib.cgc_body_free(body)
    # The R-tree and brute force (the test oracle) list the same owners of every point as the
    # lattice search, each with its xi to 1e-9.
    if os.environ.get("AUDIT_STRATEGIES"):
        lattice = {(p, int(g["cell"])): [float(g[k]) for k in ("xi", "eta", "zeta")] for p, got in rows.items() for g in got}
        for strategy in ("rtree", "brute"):
            rs, outs = run(wd, mesh, pts, ["--all-owners", "--strategy", strategy])
            other = {}
            if rs.returncode == 0:
                with open(outs) as f:
                    for g in csv.DictReader(f):
                        if int(g["cell"]) >= 0:
                            other[(int(g["point"]), int(g["cell"]))] = [float(g[k]) for k in ("xi", "eta", "zeta")]
            mine = {k: v for k, v in lattice.items() if k[1] >= 0}
            differ = set(mine) ^ set(other)
            far = [k for k in set(mine) & set(other) if max(abs(a - b) for a, b in zip(mine[k], other[k])) > 1e-9]
            if rs.returncode != 0 or differ or far:
                bad += 1
                ok = False
                print("STRATEGY", strategy, tag, "rc", rs.returncode, "owners only one side", sorted(differ)[:5], "xi apart", far[:5], rs.stderr[-200:])
    # The same mesh as a parallel file: its cells dealt at random into 2 to 4 pieces (each with its
    # own copy of the nodes it uses), with a ghost layer on some seeds (the cells sharing a node
    # with a piece's own, flagged in vtkGhostType), each piece written by VTK's XML writer, the
    # .pvtu written here. Every owner of every point (cells mapped back to the serial file's) is
    # the serial file's, bit for bit, and no answer names a ghost copy.
    if not legacy and os.environ.get("AUDIT_PVTU"):
        pv, pieces, piece_cells, ghost_cells = write_pvtu(wd, fp, fu, hexes, rng)
        rp, outp = run(wd, pv, pts, ["--all-owners"])
        serial = {p: sorted((int(g["cell"]), g["xi"], g["eta"], g["zeta"]) for g in got) for p, got in rows.items()}
        mapped, ghost_named = {}, 0
        if rp.returncode == 0:
            with open(outp) as f:
                for g in csv.DictReader(f):
                    c = int(g["cell"])
                    ghost_named += c in ghost_cells
                    mapped.setdefault(int(g["point"]), []).append((piece_cells[c] if c >= 0 else -1, g["xi"], g["eta"], g["zeta"]))
        mapped = {p: sorted(v) for p, v in mapped.items()}
        if rp.returncode != 0 or mapped != serial or ghost_named:
            bad += 1
            ok = False
            differ = [p for p in serial if serial[p] != mapped.get(p)]
            print("PVTU", tag, "pieces", pieces, "ghosts", len(ghost_cells), "rc", rp.returncode,
                  "points differ", differ[:5], "ghost answers", ghost_named, rp.stderr[-300:])
        # With AUDIT_MPI, mpirun on the parallel file writes its CLI results file byte for byte.
        if os.environ.get("AUDIT_MPI") and rp.returncode == 0:
            gap = ["--gap", repr(float(max(h)))]
            rq, outq = run(wd, pv, pts, gap)
            with open(outq, "rb") as f:
                want_bytes = f.read()
            outm = os.path.join(wd, "mpi-pvtu.csv")
            if os.path.exists(outm):
                os.remove(outm)
            root = ["--allow-run-as-root"] if os.geteuid() == 0 else []
            rm = subprocess.run(["mpirun", "--oversubscribe", *root, "-np", "3", os.environ["AUDIT_MPI"], "locate",
                                 "--mesh", pv, "--points", os.path.join(wd, "points.csv"), "--out", outm,
                                 "-q", *gap], capture_output=True, text=True)
            if not (rm.returncode == 0 and os.path.exists(outm) and open(outm, "rb").read() == want_bytes):
                bad += 1
                ok = False
                print("PVTU MPI", tag, "rc", rm.returncode, rm.stderr[-300:])
    # MPI: `cgcontact-mpi locate` under mpirun, 2 and 3 ranks, each partition, writes the CLI's
    # results file byte for byte (one owner per point, and the gap columns).
    if os.environ.get("AUDIT_MPI"):
        for extra in ([], ["--gap", repr(float(max(h)))]):
            r1, out1 = run(wd, mesh, pts, extra)
            if r1.returncode != 0:
                bad += 1
                ok = False
                print("MPI", tag, "the CLI failed:", r1.stderr[-300:])
                continue
            with open(out1, "rb") as f:
                want_bytes = f.read()
            for ranks, partition in ((2, "slabs"), (3, "morton"), (3, "random")):
                outm = os.path.join(wd, "mpi.csv")
                if os.path.exists(outm):
                    os.remove(outm)
                root = ["--allow-run-as-root"] if os.geteuid() == 0 else []
                rm = subprocess.run(["mpirun", "--oversubscribe", *root, "-np", str(ranks), os.environ["AUDIT_MPI"], "locate",
                                     "--mesh", mesh, "--points", os.path.join(wd, "points.csv"), "--out", outm,
                                     "--partition", partition, "-q", *extra], capture_output=True, text=True)
                same = rm.returncode == 0 and os.path.exists(outm) and open(outm, "rb").read() == want_bytes
                if not same:
                    bad += 1
                    ok = False
                    print("MPI", tag, ranks, "ranks", partition, extra, "rc", rm.returncode, rm.stderr[-300:])
    if r.stderr.strip():
        print("  stderr:", r.stderr.strip()[:300])
    print("ok " if ok else "BAD", tag, "points", count, "bad", bad, {k: summary.get(k) for k in ("located", "not_found", "warnings") if k in summary})
    return ok


if __name__ == "__main__":
    seeds = range(int(sys.argv[1]), int(sys.argv[2]))
    allok = True
    for s in seeds:
        rng = random.Random(s)
        L = int(os.environ.get("AUDIT_L", "-1"))
        L = rng.choice([1, 2, 3, 4, 5]) if L < 0 else L
        n = tuple(rng.randint(1, 4) for _ in range(3))
        kind = rng.random()
        if kind < 0.25:
            origin, h = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
        elif kind < 0.5:
            origin, h = (1e6, -2e6, 3e5), (1e-3, 2.5e-3, 7e-4)
        elif kind < 0.75:
            origin, h = (-3.0, 5.0, 1e3), (1e-3, 1.0, 1e3)
        else:
            origin, h = (1e-9, -2e-9, 0.0), (1e-9, 3e-9, 2e-9)
        shift = (rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(-4, 4)) if rng.random() < 0.3 else (0.0, 0.0, 0.0)
        legacy = rng.random() < 0.4
        binary = rng.random() < 0.7
        allok &= check(s, n, L, origin, h, legacy=legacy, binary=binary, p_refine=rng.uniform(0.2, 0.7), p_hole=rng.choice([0.0, 0.05, 0.2]), shift=shift)
    print("ALL OK" if allok else "SOME BAD", "in", WORK)
    sys.exit(0 if allok else 1)
