"""Contact search on cartesian hexahedral lattices: numpy in, numpy out.

Find the hexahedron of a deformed body holding each point and its local coordinates xi in
[-1, 1]^3 (VTK corner 0 at (-1, -1, -1)), every cell holding a point, and signed gaps to the
body's deformed boundary surface. Queries release the GIL; C-contiguous, aligned float64 (n, 3)
arrays are read in place (do not write to them from another thread while a call runs), anything
else array-like is converted once; an empty list is no points. Complex, boolean (but for `Body`'s
`active` flags), text, date and time arrays, object arrays holding text, booleans, complex
numbers, None or numpy dates and times, and masked arrays with masked values, raise ValueError
rather than being cast, as do Python ints beyond float64 (or, for `hexes`, int64). Errors name the
argument at fault.
"""

import os
from typing import Dict, List, Literal, Optional, Sequence, Tuple, Union, final, overload

import numpy as np
import numpy.typing as npt

__all__ = ["Body", "Locator", "read_mesh", "_data_address", "__version__"]

__version__: str

_Strategy = Literal["lattice", "centroid", "noderad", "noderad-seed", "rtree", "brute"]
_Xi = Tuple[float, float, float]

@final
class Body:
    """A deformed body of hexahedra on a cartesian lattice (uniform, or adaptive: dyadic
    refinements of one with hanging nodes). Locators made from it share it and see every later
    `set_displacements`."""

    def __new__(
        cls,
        origin: Sequence[float],
        spacing: Sequence[float],
        counts: Sequence[int],
        active: Optional[npt.ArrayLike] = None,
    ) -> "Body":
        """A body on a lattice of `counts` cells per axis (MemoryError when it does not fit in
        memory: about 48 bytes a node). `active`: one flag per lattice cell
        (booleans, or 0s and 1s), x fastest (flat, or shape (nz, ny, nx)); None for every cell.
        Other shapes and values, and complex, text, date and time arrays, raise ValueError.
        Cells are numbered i + nx (j + ny k); `set_displacements` takes one row per lattice
        node, i + (nx + 1)(j + (ny + 1) k)."""
    @staticmethod
    def from_hexes(nodes: npt.ArrayLike, hexes: npt.ArrayLike) -> "Body":
        """A body from undeformed nodes (n, 3) and hexahedra (m, 8) of 0-based node numbers in
        VTK order (whole numbers: 2.5 or NaN raise ValueError); the lattice is detected. Cells
        are numbered by their row in `hexes`. Nodes off the lattice by their coordinates'
        rounding (32-bit floats) stay where given, before and after `set_displacements`.
        MemoryError when the body, or detecting its lattice, does not fit in memory."""
    def set_displacements(self, u: npt.ArrayLike, fill_hanging: bool = False) -> None:
        """Sets every displacement in place: one row (ux, uy, uz) per node (`node_count`). On an
        adaptive body a hanging node's row must be its constraint's value unless `fill_hanging`.
        On error (ValueError) the body keeps its displacements."""
    def inverted_cells(self) -> npt.NDArray[np.int64]:
        """The cells the current displacements invert (det J <= 0 at a corner: a node moved
        through its neighbours), ascending, numbered as `Locator.locate` numbers cells; empty
        when none. Answers in or near them are not to be trusted (a point in one may be found in
        no cell). Updates do not check for them: this costs one pass over every cell, so call it
        when wanted, not on every update. `cgcontact locate --json` reports the same cells."""
    def unresolved_cells(self) -> npt.NDArray[np.int64]:
        """The cells that f64 coordinates of their magnitude cannot resolve through their
        deformation, ascending, numbered as `Locator.locate` numbers cells; empty when none. Far
        from the origin, a cell sheared or crushed enough turns a coordinate's rounding
        (4 eps |x|) into more than a tenth of itself, and a point that close to one of its faces
        may be given the cell beside it as well. One pass over every cell, as `inverted_cells`;
        `cgcontact locate --json` reports the same cells."""
    @property
    def node_count(self) -> int:
        """Rows `set_displacements` takes."""
    @property
    def cell_count(self) -> int:
        """Cells searched: active cells, or an adaptive body's leaves."""
    @property
    def is_adaptive(self) -> bool: ...
    @property
    def hanging_count(self) -> int: ...

@final
class Locator:
    """Finds the cell of a body holding each point. Each query searches the body's current
    displacements."""

    def __new__(
        cls,
        body: Body,
        strategy: _Strategy = "lattice",
        precision: Literal["f64", "f32"] = "f64",
        tol: Optional[float] = None,
        max_iter: Optional[int] = None,
        threads: Optional[int] = None,
    ) -> "Locator":
        """`precision` "f32" on a body whose finest spacing lies outside [1e-11, 1e11] raises
        ValueError (use "f64"). `tol`: Newton step tolerance in xi units (default 1e-10 in f64,
        1e-5 in f32; above 1e-3 a UserWarning, as `cgcontact --tol` warns: answers can be off by
        about tol^2 and points near faces put in the wrong cell); `max_iter`: Newton iterations per
        candidate cell; `threads`: a pool of its own, 1 to 1024 (None: every core). `max_iter`,
        `threads`, `tol`, `gap`'s `dist` and `Body`'s `origin`, `spacing` and `counts` refuse
        booleans, Python's or numpy's (`numpy.True_`, boolean arrays) (TypeError)."""
    @property
    def strategy(self) -> _Strategy: ...
    def locate(
        self,
        points: npt.ArrayLike,
        out: Optional[Tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]] = None,
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """(cell int64[n], xi float64[n, 3]) for points (n, 3): -1 and NaN where no cell holds
        the point. Cells are numbered as the body's input (rows of `hexes`, cells of the file,
        or lattice cells). A NaN or infinite point raises ValueError naming its row, before
        anything is written. With
        `out=(cell, xi)` (C-contiguous, aligned, writeable int64[n] and float64[n, 3] arrays
        sharing no memory with `points` or each other, nor in use by a call in another thread)
        the answers are written there and `out` is returned. On a large body (more than 8 MB
        of nodal data: about 350,000 nodes in f64, 520,000 in f32), a batch of 16,384 points
        or more not already in order is answered whole, so that the library can sort it by
        cell: the call then holds about 100 bytes per point of buffers, of which the
        answers' 56 stay with the locator for its next call (a solver loop's next batch)."""
    def locate_unordered(
        self,
        points: npt.ArrayLike,
        out: Optional[
            Tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.float64]]
        ] = None,
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """(order int64[n], cell int64[n], xi float64[n, 3]): `locate`'s answers without putting
        them back in the points' order; row k of cell and xi answers point order[k], each point
        once. A batch the library sorts by cell comes cell by cell, saving a store to a random
        place per point; otherwise order[k] is k. A NaN or infinite point raises ValueError
        naming its row in `points`. With `out=(order, cell, xi)` (C-contiguous, aligned,
        writeable, sharing no memory) the answers are written there and `out` is returned. A
        sorted batch holds about 110 bytes per point of buffers, of which 64 stay with the
        locator for its next call."""
    def relocate(
        self,
        points: npt.ArrayLike,
        out: Tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]],
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """`locate` warm started, for a solver loop: `out=(cell, xi)` holds each point's previous
        answer (cell -1 for none) and is overwritten with the new one, then returned. A point
        whose previous cell still holds it costs one Newton inversion from its previous xi. The
        answers are `locate`'s whatever the hints; a cell that is neither -1 nor a cell of the
        body (an inactive lattice cell included), or a NaN or infinite point, raises ValueError
        before anything is written."""
    @overload
    def locate_owners(self, x: Sequence[float]) -> List[Tuple[int, _Xi]]: ...
    @overload
    def locate_owners(
        self, x: npt.ArrayLike
    ) -> Union[List[Tuple[int, _Xi]], List[List[Tuple[int, _Xi]]]]:
        """Every cell holding the point x (3,): [(cell, xi), ...], cells ascending; for x of
        shape (n, 3), one such list per point. Not with strategy "noderad-seed" (ValueError:
        its loose Newton misses owners)."""
    def gap(self, points: npt.ArrayLike, dist: float) -> Dict[str, np.ndarray]:
        """Signed gaps to the deformed boundary surface within `dist`: "gap" float64[n]
        (negative inside), "closest" float64[n, 3], "normal" float64[n, 3] (point = closest +
        gap * normal), "face_cell" int64[n], "face" int32[n] (VTK local face 0-5); NaN and -1
        where the surface is farther than `dist`. `dist`: at least 0 and at most 1e150. The
        sign follows `locate` in this locator's precision: negative where it finds a cell."""

def read_mesh(
    path: Union[str, os.PathLike],
    displacement: Optional[str] = "displacement",
    strict: bool = False,
) -> Body:
    """Reads a VTK mesh (.vtk, .vtu or .pvtu) as `cgcontact locate --mesh` does. `displacement`: the
    point-data array ("displacement": used if present; another name: required; None: read
    undeformed). Cells are numbered by their place in the file. A file the operating system
    refuses raises the OSError of its errno (FileNotFoundError, PermissionError,
    IsADirectoryError...); a file that is not a usable mesh, a ValueError."""

def _data_address(points: npt.ArrayLike) -> int:
    """The address of the first value the bindings read for `points` (a test probe)."""
