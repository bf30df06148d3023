//! Test helpers: bodies with holes, shuffled meshes, and VTK text written by hand the way VTK and
//! ParaView write it (so the reader is checked against files it did not write itself).
#![allow(dead_code)]

use bitvec::vec::BitVec;
use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, Body, CellId, Lattice};
use cgcontact_io::HexMesh;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub mod legacy_fixtures;
pub mod probes;

/// [`body_with_holes`] at (1, −2, 0.5), spacing 0.5, 3 × 2 × 2 cells, as a mesh carrying
/// displacements that are not all zero (dropping them would change every answer).
pub fn displaced_mesh(seed: u64) -> cgcontact_io::HexMesh {
    let body = body_with_holes(
        DVec3::new(1.0, -2.0, 0.5),
        DVec3::splat(0.5),
        [3, 2, 2],
        seed,
    );
    let mut mesh = cgcontact_io::HexMesh::from_body(&body);
    mesh.displacement = Some(
        mesh.points
            .iter()
            .map(|p| DVec3::new(0.01 * p.y, -0.02 * p.x, 0.005))
            .collect(),
    );
    mesh
}

/// A lattice body with about a fifth of its cells missing (the two extreme corner cells kept, so the
/// detected lattice is the same) and a smooth displacement of about a tenth of a cell.
pub fn body_with_holes(origin: DVec3, h: DVec3, n: [u32; 3], seed: u64) -> Body {
    let lattice = Lattice::new(origin, h, n).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut active = BitVec::repeat(true, lattice.cell_count());
    for c in 1..lattice.cell_count() - 1 {
        if rng.random_bool(0.2) {
            active.set(c, false);
        }
    }
    let mut body = Body::undeformed(lattice, active).unwrap();
    body.update_displacements(|_, x, u| {
        let t = (x - origin) / h;
        *u = 0.1
            * h
            * DVec3::new(
                (t.y * 0.7).sin(),
                (t.z * 0.3 + t.x).cos(),
                (t.x * 0.5).sin() * 0.5,
            );
    })
    .unwrap();
    body
}

/// The mesh with its cells and nodes in random order; `perm[new] = old` cell index.
pub fn shuffled(mesh: &HexMesh, seed: u64) -> (HexMesh, Vec<usize>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut cell_perm: Vec<usize> = (0..mesh.cells.len()).collect();
    cell_perm.shuffle(&mut rng);
    let mut node_perm: Vec<usize> = (0..mesh.points.len()).collect();
    node_perm.shuffle(&mut rng);
    // node_perm[new] = old; new_of_old[old] = new.
    let mut new_of_old = vec![0u32; node_perm.len()];
    for (new, &old) in node_perm.iter().enumerate() {
        new_of_old[old] = new as u32;
    }
    let points = node_perm.iter().map(|&o| mesh.points[o]).collect();
    let displacement = mesh
        .displacement
        .as_ref()
        .map(|u| node_perm.iter().map(|&o| u[o]).collect());
    let cells = cell_perm
        .iter()
        .map(|&c| mesh.cells[c].map(|n| new_of_old[n as usize]))
        .collect();
    (
        HexMesh {
            ghosts: Vec::new(),
            points,
            cells,
            displacement,
        },
        cell_perm,
    )
}

/// How a hand-written legacy file carries the displacement.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum LegacyData {
    None,
    Vectors,
    /// `FIELD FieldData 1` with a `displacement 3 n double` array, as VTK 9 often writes.
    Field,
}

/// A legacy ASCII file as VTK writes it (version 4.2 `CELLS n size` or 5.1 `OFFSETS`/`CONNECTIVITY`).
pub fn legacy_ascii(mesh: &HexMesh, data: LegacyData, v51: bool) -> String {
    let mut s = String::new();
    s += if v51 {
        "# vtk DataFile Version 5.1\n"
    } else {
        "# vtk DataFile Version 4.2\n"
    };
    s += "vtk output\nASCII\nDATASET UNSTRUCTURED_GRID\n";
    s += &format!("POINTS {} double\n", mesh.points.len());
    for p in &mesh.points {
        s += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    let n = mesh.cells.len();
    if v51 {
        s += &format!("CELLS {} {}\nOFFSETS vtktypeint64\n", n + 1, 8 * n);
        s += &(0..=n)
            .map(|c| (8 * c).to_string())
            .collect::<Vec<_>>()
            .join(" ");
        s += "\nCONNECTIVITY vtktypeint64\n";
        for c in &mesh.cells {
            s += &c.map(|v| v.to_string()).join(" ");
            s += "\n";
        }
    } else {
        s += &format!("CELLS {} {}\n", n, 9 * n);
        for c in &mesh.cells {
            s += &format!("8 {}\n", c.map(|v| v.to_string()).join(" "));
        }
    }
    s += &format!("CELL_TYPES {n}\n");
    for _ in 0..n {
        s += "12\n";
    }
    if let (Some(u), true) = (&mesh.displacement, data != LegacyData::None) {
        s += &format!("POINT_DATA {}\n", mesh.points.len());
        if data == LegacyData::Vectors {
            s += "VECTORS displacement double\n";
        } else {
            s += &format!("FIELD FieldData 1\ndisplacement 3 {} double\n", u.len());
        }
        for v in u {
            s += &format!("{} {} {}\n", v.x, v.y, v.z);
        }
    }
    s
}

fn join<T: std::fmt::Display>(values: impl IntoIterator<Item = T>) -> String {
    values
        .into_iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join(" ")
}

/// A `.vtu` with ascii arrays, as ParaView writes it (Int64 connectivity/offsets, UInt8 types).
pub fn vtu_ascii(mesh: &HexMesh) -> String {
    let n = mesh.cells.len();
    let mut s = String::new();
    s += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n";
    s += &format!(
        "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{n}\">\n",
        mesh.points.len()
    );
    s += "      <PointData Vectors=\"displacement\">\n";
    if let Some(u) = &mesh.displacement {
        s += "        <DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
        s += &join(u.iter().flat_map(|v| v.to_array()));
        s += "\n        </DataArray>\n";
    }
    s += "      </PointData>\n      <CellData>\n      </CellData>\n      <Points>\n";
    s += "        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    s += &join(mesh.points.iter().flat_map(|v| v.to_array()));
    s += "\n        </DataArray>\n      </Points>\n      <Cells>\n";
    s += "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
    s += &join(mesh.cells.iter().flatten());
    s += "\n        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
    s += &join((1..=n).map(|c| 8 * c));
    s += "\n        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    s += &join(std::iter::repeat_n(12, n));
    s +=
        "\n        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
    s
}

/// A zlib stream of stored (uncompressed) deflate blocks: valid for any zlib reader, no
/// compression library needed in the tests.
fn zlib_stored(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    let chunks: Vec<&[u8]> = if data.is_empty() {
        vec![&[]]
    } else {
        data.chunks(65535).collect()
    };
    for (i, chunk) in chunks.iter().enumerate() {
        out.push(u8::from(i + 1 == chunks.len()));
        let len = chunk.len() as u16;
        out.extend(len.to_le_bytes());
        out.extend((!len).to_le_bytes());
        out.extend_from_slice(chunk);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &byte in data {
        a = (a + u32::from(byte)) % 65521;
        b = (b + a) % 65521;
    }
    out.extend(((b << 16) | a).to_be_bytes());
    out
}

/// A `.vtu` with raw appended data, as ParaView writes it by default (optionally zlib-compressed in
/// blocks of `block` bytes), with a UInt64 or UInt32 header.
pub fn vtu_raw_appended(mesh: &HexMesh, compressed: bool, header64: bool, block: usize) -> Vec<u8> {
    let zlib = compressed.then_some(("vtkZLibDataCompressor", zlib_stored as fn(&[u8]) -> Vec<u8>));
    raw_appended_with(mesh, zlib, header64, block)
}

/// `vtu_raw_appended` compressed with VTK's LZMA compressor: each block an .xz stream (lzma-rs's
/// encoder, which stores the bytes in uncompressed LZMA2 chunks, without a check).
pub fn vtu_raw_appended_lzma(mesh: &HexMesh, header64: bool, block: usize) -> Vec<u8> {
    fn xz(data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        lzma_rs::xz_compress(&mut &data[..], &mut out).unwrap();
        out
    }
    raw_appended_with(
        mesh,
        Some(("vtkLZMADataCompressor", xz as fn(&[u8]) -> Vec<u8>)),
        header64,
        block,
    )
}

/// A compressor: its name in a file's `compressor` attribute, and what it does to one block.
type Compressor = (&'static str, fn(&[u8]) -> Vec<u8>);

/// A raw appended `.vtu`, its blocks compressed by `compressor` if any.
fn raw_appended_with(
    mesh: &HexMesh,
    compressor: Option<Compressor>,
    header64: bool,
    block: usize,
) -> Vec<u8> {
    let compressed = compressor.is_some();
    let n = mesh.cells.len();
    let header = |v: usize| -> Vec<u8> {
        if header64 {
            (v as u64).to_le_bytes().to_vec()
        } else {
            (v as u32).to_le_bytes().to_vec()
        }
    };
    let encode = |bytes: Vec<u8>| -> Vec<u8> {
        if !compressed {
            let mut out = header(bytes.len());
            out.extend(bytes);
            return out;
        }
        let blocks: Vec<&[u8]> = bytes.chunks(block).collect();
        let last = bytes.len() % block;
        let compress = compressor.map(|(_, f)| f).unwrap();
        let zipped: Vec<Vec<u8>> = blocks.iter().map(|b| compress(b)).collect();
        let mut out = header(blocks.len());
        out.extend(header(block));
        out.extend(header(last));
        for z in &zipped {
            out.extend(header(z.len()));
        }
        for z in zipped {
            out.extend(z);
        }
        out
    };
    let f64s = |v: Vec<f64>| {
        v.into_iter()
            .flat_map(f64::to_le_bytes)
            .collect::<Vec<u8>>()
    };
    let i64s = |v: Vec<i64>| {
        v.into_iter()
            .flat_map(i64::to_le_bytes)
            .collect::<Vec<u8>>()
    };
    let mut arrays: Vec<(String, Vec<u8>)> = Vec::new();
    if let Some(u) = &mesh.displacement {
        arrays.push((
            "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"appended\" RangeMin=\"0\" RangeMax=\"1\" offset=\"{}\"/>".into(),
            encode(f64s(u.iter().flat_map(|v| v.to_array()).collect())),
        ));
    }
    arrays.push((
        "<DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{}\"/>".into(),
        encode(f64s(mesh.points.iter().flat_map(|v| v.to_array()).collect())),
    ));
    arrays.push((
        "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"appended\" offset=\"{}\"/>"
            .into(),
        encode(i64s(
            mesh.cells.iter().flatten().map(|&v| i64::from(v)).collect(),
        )),
    ));
    arrays.push((
        "<DataArray type=\"Int64\" Name=\"offsets\" format=\"appended\" offset=\"{}\"/>".into(),
        encode(i64s((1..=n as i64).map(|c| 8 * c).collect())),
    ));
    arrays.push((
        "<DataArray type=\"UInt8\" Name=\"types\" format=\"appended\" offset=\"{}\"/>".into(),
        encode(vec![12u8; n]),
    ));
    let mut offset = 0;
    let mut tags = Vec::new();
    let mut blob = Vec::new();
    for (tag, bytes) in &arrays {
        tags.push(tag.replace("{}", &offset.to_string()));
        offset += bytes.len();
        blob.extend_from_slice(bytes);
    }
    let (first_point_array, rest) = if mesh.displacement.is_some() {
        (Some(&tags[0]), &tags[1..])
    } else {
        (None, &tags[..])
    };
    let mut s = String::new();
    s += &format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"{}\" byte_order=\"LittleEndian\"{}{}>\n",
        if header64 { "1.0" } else { "0.1" },
        if header64 {
            " header_type=\"UInt64\""
        } else {
            ""
        },
        compressor.map_or_else(String::new, |(name, _)| format!(" compressor=\"{name}\""))
    );
    s += &format!(
        "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{n}\">\n",
        mesh.points.len()
    );
    s += "      <PointData Vectors=\"displacement\">\n";
    if let Some(t) = first_point_array {
        s += &format!("        {t}\n");
    }
    s += "      </PointData>\n      <CellData>\n      </CellData>\n      <Points>\n";
    s += &format!("        {}\n      </Points>\n      <Cells>\n", rest[0]);
    for t in &rest[1..] {
        s += &format!("        {t}\n");
    }
    s += "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _";
    let mut out = s.into_bytes();
    out.extend(blob);
    out.extend_from_slice(b"\n  </AppendedData>\n</VTKFile>\n");
    out
}

/// Expected lattice cell of each input cell of a shuffled `HexMesh::from_body(body)`.
pub fn expected_cells(body: &Body, perm: &[usize]) -> Vec<CellId> {
    let active: Vec<CellId> = body.active_cells().collect();
    perm.iter().map(|&old| active[old]).collect()
}

/// The explicit mesh of an adaptive `body`: nodes in node order, cells in leaf order.
pub fn mesh_of(body: &AdaptiveBody) -> HexMesh {
    HexMesh {
        ghosts: Vec::new(),
        points: (0..body.node_count())
            .map(|n| body.node_position(n).unwrap())
            .collect(),
        cells: (0..body.cell_count() as u32)
            .map(|c| body.cell_nodes(CellId(c)).unwrap().map(|n| n as u32))
            .collect(),
        displacement: Some(body.displacements().to_vec()),
    }
}
