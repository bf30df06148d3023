//! # cgcontact-io
//!
//! Reading and writing the files of [`cgcontact`]: VTK meshes in, lattice bodies out; CSV points in,
//! CSV results out; VTK files for ParaView.
//!
//! | piece | what it does |
//! |---|---|
//! | [`read_mesh`] | a VTK unstructured grid of hexahedra (legacy `.vtk` ASCII/binary, XML `.vtu` ascii/base64/appended, raw or zlib/LZ4/LZMA-compressed, or a parallel `.pvtu` and its pieces) → [`LatticeMesh`]: the [`Body`](cgcontact::Body) plus the [`CellMap`] between the input's cell order and lattice cells |
//! | [`MeshFile`] | [`read_body`] in two steps: the file read once and parsed, a `.pvtu`'s piece files listed before any is read ([`MeshFile::piece_files`]), then the body and the names of its point arrays ([`MeshFile::into_body`]) |
//! | [`HexMesh::to_lattice`] | lattice detection: origin, spacing per axis and counts from the nodes (to 1e-9 of the spacing), every cell checked to be one lattice cube in VTK corner order |
//! | [`write_mesh`] | a body in any of the three flavours ([`MeshFormat`]); [`read_mesh`] reads it back exactly |
//! | [`read_points`], [`write_results`], [`read_results`] | CSV points `x,y,z` and results `point,cell,xi,eta,zeta,...` ([`read_points_with_warning`]: the points, and a warning for a file whose last line has no line end, from one read) |
//! | [`write_deformed_vtu`], [`write_points_vtu`] | the deformed mesh (cells with `points_held`, `active`) and the located points (`cell`, `xi`) for ParaView |
//! | [`read_text`] | any other text input (a benchmark's log, say): read whole within its own size limit, refused at its first NUL byte |
//! | [`CallerBody`], [`NodeSources`] | a body as the C and Python bindings' callers hold it: cells and nodes in the caller's numbering, displacements set in place from the caller's nodes and checked first ([`UpdateError`], worded by each binding) |
//!
//! Every file is written whole or not at all ([`write_file`]: a temporary file renamed over the
//! target), and every error is an [`IoError`] naming the file and the offending line, cell or node; no input
//! makes this crate panic. `docs/formats.md` describes the formats as implemented.
//!
//! ```
//! use cgcontact::{Body, Lattice, LatticeLocator, Locator, Settings};
//! use cgcontact::glam::DVec3;
//! use cgcontact_io::{CellMap, DisplacementArray, MeshFormat, read_mesh, read_results, write_mesh, write_results};
//!
//! let dir = tempfile::tempdir()?;
//! // A body saved as a scene file...
//! let mut body = Body::full(Lattice::new(DVec3::new(1e3, 0.0, 0.0), DVec3::splat(0.5), [4, 2, 2])?);
//! body.update_displacements(|_, x, u| *u = DVec3::new(0.0, 0.0, -0.01 * (x.x - 1e3)))?;
//! let path = dir.path().join("block.vtu");
//! write_mesh(&path, &body, MeshFormat::Xml)?;
//!
//! // ... read back as a user's mesh: the lattice is detected from the nodes.
//! let mesh = read_mesh(&path, &DisplacementArray::Default)?;
//! assert_eq!(mesh.body.lattice().cells(), [4, 2, 2]);
//! assert_eq!(mesh.body.displacements(), body.displacements());
//!
//! // Locate points and write results with the input's cell numbers.
//! let locator = LatticeLocator::new(&mesh.body, Settings::default())?;
//! let answers = locator.locate_all(&[DVec3::new(1000.3, 0.2, 0.4), DVec3::splat(-5.0)]);
//! let results = dir.path().join("results.csv");
//! write_results(&results, &answers, &mesh.cells)?;
//! let rows = read_results(&results)?;
//! assert_eq!(rows[0].cell, Some(0));
//! assert_eq!(rows[1].cell, None);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod adaptive_mesh;
mod appended_sizes;
mod atomic;
mod block_headers;
mod caller_body;
mod csv_io;
mod error;
mod input;
mod legacy_sections;
mod legacy_strings;
mod legacy_types;
mod lzma_arrays;
mod mesh;
mod node_sources;
mod raw_appended;
mod vtk_read;
mod vtk_write;
mod xml_cells;
mod xml_normal;

pub use adaptive_mesh::{AdaptiveMesh, MeshBody};
pub use atomic::{
    Descriptor, abandon_writes, abandon_writes_within, check_replaceable, descriptor, piece_file,
    same_file, write_file, write_target,
};
pub use caller_body::{AnyBody, CallerBody, Kept, KeptBuffers, UpdateError};
pub use csv_io::{
    GAP_HEADER, Num, RESULTS_HEADER, ResultRow, parse_points, parse_results, read_points,
    read_points_with_warning, read_results, unended_points_file, write_owner_rows, write_points,
    write_results, write_results_counted, write_results_to,
};
pub use error::{ErrorKind, IoError};
pub use input::{
    DEFAULT_MAX_INPUT_BYTES, MAX_INPUT_BYTES_VAR, TextInput, max_input_bytes, read_text,
};
pub use mesh::{CellMap, CellNumbering, HexMesh, LATTICE_TOLERANCE, LatticeMesh};
pub use node_sources::NodeSources;
pub use vtk_read::{
    DEFAULT_DISPLACEMENT, DisplacementArray, MeshFile, MeshRead, parse_hex_mesh, read_body,
    read_hex_mesh, read_mesh,
};
pub use vtk_write::{
    MeshFormat, write_adaptive_mesh, write_deformed_adaptive_vtu, write_deformed_vtu, write_mesh,
    write_points_vtu,
};

/// `message` on one line: its control characters escaped (`\n` for a newline). The parsers'
/// own messages may quote a file's text, newlines included.
pub(crate) fn one_line(message: &str) -> String {
    if !message.chars().any(char::is_control) {
        return message.to_owned();
    }
    message
        .chars()
        .flat_map(|c| {
            let escape = c.is_control();
            c.escape_default()
                .filter(move |_| escape)
                .chain(std::iter::once(c).filter(move |_| !escape))
        })
        .collect()
}

/// A piece of an input for an error message: at most `max_chars` characters, control characters
/// and undecodable bytes escaped, in backticks, so that a binary file never reaches the terminal.
pub(crate) fn excerpt(bytes: &[u8], max_chars: usize) -> String {
    let text = String::from_utf8_lossy(bytes);
    let mut out = String::from("`");
    for (i, c) in text.chars().enumerate() {
        if i == max_chars {
            out.push('…');
            break;
        }
        if c.is_control() || c == char::REPLACEMENT_CHARACTER {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out.push('`');
    out
}
