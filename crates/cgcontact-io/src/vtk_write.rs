//! Writing VTK files with vtkio: bodies in all three flavours (for scenes and round trips), and the
//! deformed mesh and located points for ParaView.

use std::path::Path;

use cgcontact::{AdaptiveBody, Answer, Body, CellId, Lattice};
use glam::DVec3;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataArray, DataSet, ElementType, IOBuffer,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};
use vtkio::xml::{Compressor, VTKFile};

use crate::{CellMap, DEFAULT_DISPLACEMENT, ErrorKind, HexMesh, IoError};

/// How [`write_mesh`] writes a body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// Legacy `.vtk`, ASCII (version 4.2; every value in Rust's shortest round-trip form, so f64s
    /// read back bitwise).
    LegacyAscii,
    /// Legacy `.vtk`, binary (version 4.2, big-endian as the format requires).
    LegacyBinary,
    /// XML `.vtu`, arrays inline as base64 binary.
    Xml,
    /// XML `.vtu`, arrays inline as base64 of zlib-compressed binary.
    XmlZlib,
}

impl MeshFormat {
    /// The usual file extension (`vtk` or `vtu`).
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            Self::LegacyAscii | Self::LegacyBinary => "vtk",
            Self::Xml | Self::XmlZlib => "vtu",
        }
    }
}

/// Write `body` as an unstructured grid of its active cells, in ascending lattice order, with
/// undeformed node coordinates and the displacement as point data `displacement`.
///
/// [`crate::read_mesh`] reads it back as the same lattice (origin exact, spacing to an ulp), the
/// same cells in the same order ([`CellMap::ascending`]), and bitwise the same displacements.
pub fn write_mesh(path: impl AsRef<Path>, body: &Body, format: MeshFormat) -> Result<(), IoError> {
    let path = path.as_ref();
    let mesh = HexMesh::from_body(body);
    let u = mesh.displacement.clone().unwrap_or_default();
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(flatten(&mesh.points)),
        cells: hex_cells(&mesh.cells),
        data: Attributes {
            point: vec![Attribute::DataArray(DataArray {
                name: DEFAULT_DISPLACEMENT.to_owned(),
                elem: ElementType::Vectors,
                data: IOBuffer::F64(flatten(&u)),
            })],
            cell: Vec::new(),
        },
    };
    write_piece(
        path,
        piece,
        format,
        "cgcontact body: undeformed lattice nodes, displacement as point data",
    )
}

/// Write the deformed mesh for ParaView (XML `.vtu`): node coordinates are undeformed + displacement.
///
/// Cells come in input order (`cells`), each with cell data `input_cell` (its index in the input
/// mesh, or −1), `lattice_cell`, `points_held` (how many of `answers` located in it) and `active`.
/// With `include_inactive`, the lattice's inactive cells follow, undeformed where no active cell
/// moves their nodes, with `active` = 0 and `input_cell` = −1 (a threshold on `active` shows the
/// body; the whole lattice shows the holes). Point data: `displacement`.
pub fn write_deformed_vtu(
    path: impl AsRef<Path>,
    body: &Body,
    cells: &CellMap,
    answers: &[Answer],
    include_inactive: bool,
) -> Result<(), IoError> {
    let path = path.as_ref();
    let lattice = *body.lattice();
    let mut order: Vec<CellId> = cells.lattice_cells().to_vec();
    if include_inactive {
        order.extend(
            (0..lattice.cell_count() as u32)
                .map(CellId)
                .filter(|&c| !body.is_active(c)),
        );
    }
    // Points held, per written cell: in the order's own indexing (no table over the lattice).
    let mut held = vec![0i32; order.len()];
    let place = |cell: CellId| -> Option<usize> {
        cells.input_cell(cell).or_else(|| {
            include_inactive
                .then(|| order[cells.len()..].binary_search(&cell).ok())
                .flatten()
                .map(|i| cells.len() + i)
        })
    };
    for hit in answers.iter().flatten().flatten() {
        if let Some(h) = place(hit.cell).and_then(|i| held.get_mut(i)) {
            *h = h.saturating_add(1);
        }
    }
    // Nodes: the corners of the written cells, numbered in ascending lattice node order.
    let mut nodes: Vec<usize> = order
        .iter()
        .flat_map(|&cell| corners(&lattice, cell))
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    let index = |n: usize| nodes.binary_search(&n).expect("a corner of a written cell") as u32;
    let mut points = Vec::with_capacity(nodes.len());
    let mut u = Vec::with_capacity(nodes.len());
    for &node in &nodes {
        let ijk = lattice.node_ijk(node).expect("node of the lattice");
        let d = body.displacement(node).unwrap_or(DVec3::ZERO);
        points.push(lattice.node_position(ijk) + d);
        u.push(d);
    }
    let connectivity: Vec<[u32; 8]> = order
        .iter()
        .map(|&c| corners(&lattice, c).map(index))
        .collect();
    let input_cell: Vec<i64> = order
        .iter()
        .map(|&c| cells.input_cell(c).map_or(-1, |i| i as i64))
        .collect();
    let lattice_cell: Vec<i64> = order.iter().map(|&c| i64::from(c.0)).collect();
    let points_held = held;
    let active: Vec<u8> = order.iter().map(|&c| u8::from(body.is_active(c))).collect();
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(flatten(&points)),
        cells: hex_cells(&connectivity),
        data: Attributes {
            point: vec![array(DEFAULT_DISPLACEMENT, 3, IOBuffer::F64(flatten(&u)))],
            cell: vec![
                array("input_cell", 1, IOBuffer::I64(input_cell)),
                array("lattice_cell", 1, IOBuffer::I64(lattice_cell)),
                array("points_held", 1, IOBuffer::I32(points_held)),
                array("active", 1, IOBuffer::U8(active)),
            ],
        },
    };
    write_piece(path, piece, MeshFormat::Xml, "cgcontact deformed mesh")
}

/// The undeformed nodes of an adaptive body (in its node order) and its leaves' corners.
fn adaptive_nodes_and_cells(body: &AdaptiveBody) -> (Vec<DVec3>, Vec<[u32; 8]>) {
    let points = (0..body.node_count())
        .map(|n| body.node_position(n).expect("node in range"))
        .collect();
    let cells = (0..body.cell_count() as u32)
        .map(|c| {
            body.cell_nodes(CellId(c))
                .expect("leaf in range")
                .map(|n| n as u32)
        })
        .collect();
    (points, cells)
}

/// Write an adaptive body: its leaves in id order, its nodes (hanging ones included) in node
/// order with undeformed coordinates, the displacement as point data `displacement`, and each
/// leaf's refinement level as cell data `level`. [`crate::read_body`] reads it back as the same
/// leaves in the same order.
pub fn write_adaptive_mesh(
    path: impl AsRef<Path>,
    body: &AdaptiveBody,
    format: MeshFormat,
) -> Result<(), IoError> {
    let path = path.as_ref();
    let (points, cells) = adaptive_nodes_and_cells(body);
    let level: Vec<u8> = body.leaves().iter().map(|l| l.level).collect();
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(flatten(&points)),
        cells: hex_cells(&cells),
        data: Attributes {
            point: vec![Attribute::DataArray(DataArray {
                name: DEFAULT_DISPLACEMENT.to_owned(),
                elem: ElementType::Vectors,
                data: IOBuffer::F64(flatten(body.displacements())),
            })],
            cell: vec![array("level", 1, IOBuffer::U8(level))],
        },
    };
    write_piece(
        path,
        piece,
        format,
        "cgcontact adaptive body: undeformed nodes, displacement as point data, level per cell",
    )
}

/// Write an adaptive body deformed for ParaView (XML `.vtu`): node coordinates undeformed +
/// displacement, cells in input order with cell data `input_cell`, `level` and `points_held` (how
/// many of `answers` located in it). Point data: `displacement`.
pub fn write_deformed_adaptive_vtu(
    path: impl AsRef<Path>,
    body: &AdaptiveBody,
    answers: &[Answer],
) -> Result<(), IoError> {
    let path = path.as_ref();
    let (undeformed, cells) = adaptive_nodes_and_cells(body);
    let points: Vec<DVec3> = undeformed
        .iter()
        .zip(body.displacements())
        .map(|(x, u)| *x + *u)
        .collect();
    let mut held = vec![0i32; body.cell_count()];
    for hit in answers.iter().flatten().flatten() {
        if let Some(h) = held.get_mut(hit.cell.index()) {
            *h = h.saturating_add(1);
        }
    }
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(flatten(&points)),
        cells: hex_cells(&cells),
        data: Attributes {
            point: vec![array(
                DEFAULT_DISPLACEMENT,
                3,
                IOBuffer::F64(flatten(body.displacements())),
            )],
            cell: vec![
                array(
                    "input_cell",
                    1,
                    IOBuffer::I64((0..body.cell_count() as i64).collect()),
                ),
                array(
                    "level",
                    1,
                    IOBuffer::U8(body.leaves().iter().map(|l| l.level).collect()),
                ),
                array("points_held", 1, IOBuffer::I32(held)),
            ],
        },
    };
    write_piece(
        path,
        piece,
        MeshFormat::Xml,
        "cgcontact deformed adaptive mesh",
    )
}

/// Write query points for ParaView (XML `.vtu` of VTK_VERTEX cells), with point data `cell` (input
/// cell index, or −1 when not located), `lattice_cell` (or −1), `xi` (local coordinates, NaN when
/// not located) and `iterations` (Newton iterations of the accepted inversion, 0 when not located).
pub fn write_points_vtu(
    path: impl AsRef<Path>,
    points: &[DVec3],
    answers: &[Answer],
    cells: &CellMap,
) -> Result<(), IoError> {
    let path = path.as_ref();
    if points.len() != answers.len() {
        return Err(ErrorKind::Mismatch(format!(
            "{} points but {} answers",
            points.len(),
            answers.len()
        ))
        .in_file(path));
    }
    let n = points.len();
    let hits = answers.iter().map(|a| a.ok().flatten());
    let cell: Vec<i64> = hits
        .clone()
        .map(|h| {
            h.and_then(|h| cells.input_cell(h.cell))
                .map_or(-1, |i| i as i64)
        })
        .collect();
    let lattice_cell: Vec<i64> = hits
        .clone()
        .map(|h| h.map_or(-1, |h| i64::from(h.cell.0)))
        .collect();
    let xi: Vec<DVec3> = hits
        .clone()
        .map(|h| h.map_or(DVec3::NAN, |h| h.xi))
        .collect();
    let iterations: Vec<i32> = hits.map(|h| h.map_or(0, |h| h.iterations as i32)).collect();
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(flatten(points)),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity: (0..n as u64).collect(),
                offsets: (1..=n as u64).collect(),
            },
            types: vec![CellType::Vertex; n],
        },
        data: Attributes {
            point: vec![
                array("cell", 1, IOBuffer::I64(cell)),
                array("lattice_cell", 1, IOBuffer::I64(lattice_cell)),
                array("xi", 3, IOBuffer::F64(flatten(&xi))),
                array("iterations", 1, IOBuffer::I32(iterations)),
            ],
            cell: Vec::new(),
        },
    };
    write_piece(path, piece, MeshFormat::Xml, "cgcontact query points")
}

fn corners(lattice: &Lattice, cell: CellId) -> [usize; 8] {
    lattice.corner_nodes(
        lattice
            .cell_ijk(cell)
            .expect("cell ids of the body's lattice"),
    )
}

fn flatten(v: &[DVec3]) -> Vec<f64> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

fn array(name: &str, components: u32, data: IOBuffer) -> Attribute {
    Attribute::DataArray(DataArray {
        name: name.to_owned(),
        elem: ElementType::Generic(components),
        data,
    })
}

fn hex_cells(cells: &[[u32; 8]]) -> Cells {
    Cells {
        cell_verts: VertexNumbers::XML {
            connectivity: cells.iter().flatten().map(|&n| u64::from(n)).collect(),
            offsets: (1..=cells.len() as u64).map(|c| 8 * c).collect(),
        },
        types: vec![CellType::Hexahedron; cells.len()],
    }
}

fn write_piece(
    path: &Path,
    piece: UnstructuredGridPiece,
    format: MeshFormat,
    title: &str,
) -> Result<(), IoError> {
    let legacy = matches!(format, MeshFormat::LegacyAscii | MeshFormat::LegacyBinary);
    let vtk = Vtk {
        version: if legacy {
            Version::new_legacy(4, 2)
        } else {
            Version::new_xml(1, 0)
        },
        title: title.to_owned(),
        byte_order: if legacy {
            ByteOrder::BigEndian
        } else {
            ByteOrder::LittleEndian
        },
        data: DataSet::inline(piece),
        file_path: None,
    };
    let fail = |e: vtkio::Error| ErrorKind::Vtk(format!("writing: {e}"));
    match format {
        MeshFormat::LegacyAscii => {
            let mut text = String::new();
            vtk.write_legacy_ascii(&mut text)
                .map_err(|e| fail(e).in_file(path))?;
            crate::atomic::write_file(path, |out| Ok(out.write_all(text.as_bytes())?))
        }
        MeshFormat::LegacyBinary => {
            crate::atomic::write_file(path, |out| vtk.write_legacy(out).map_err(fail))
        }
        MeshFormat::Xml | MeshFormat::XmlZlib => {
            let (compressor, level) = if format == MeshFormat::XmlZlib {
                (Compressor::ZLib, 6)
            } else {
                (Compressor::None, 0)
            };
            let file: VTKFile = vtk
                .try_into_xml_format(compressor, level)
                .map_err(|e| fail(e.into()).in_file(path))?;
            crate::atomic::write_file(path, |out| file.write(out).map_err(|e| fail(e.into())))
        }
    }
}
