//! Reading VTK unstructured grids of hexahedra (legacy `.vtk` ASCII/binary, XML `.vtu`, parallel `.pvtu`) with vtkio.

use std::borrow::Cow;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use glam::DVec3;
use vtkio::model::{
    Attribute, CellType, DataSet, Piece, UnstructuredGridPiece, VertexNumbers, Vtk,
};

use crate::{
    ErrorKind, HexMesh, IoError, LatticeMesh, MeshBody, block_headers, legacy_sections,
    legacy_strings, legacy_types, lzma_arrays, raw_appended, xml_cells, xml_normal,
};

/// The point-data array used when the caller names none.
pub const DEFAULT_DISPLACEMENT: &str = "displacement";

/// Which point-data array holds the displacement.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum DisplacementArray {
    /// The array named [`DEFAULT_DISPLACEMENT`] if the file has one; otherwise the mesh is undeformed.
    #[default]
    Default,
    /// The array with this name; a file without it is an error.
    Named(String),
    /// None: read the mesh undeformed whatever the file holds.
    Ignore,
}

impl DisplacementArray {
    /// `Named(name)` for `Some(name)`, `Default` for `None` (a command line's optional flag).
    #[must_use]
    pub fn from_option(name: Option<&str>) -> Self {
        name.map_or(Self::Default, |n| Self::Named(n.to_owned()))
    }
}

/// Read a VTK mesh file and recognise it as a lattice body (see [`HexMesh::to_lattice`]).
///
/// The format is told from the content, not the extension: a legacy file starts with
/// `# vtk DataFile`, an XML file with `<`.
pub fn read_mesh(
    path: impl AsRef<Path>,
    displacement: &DisplacementArray,
) -> Result<LatticeMesh, IoError> {
    let path = path.as_ref();
    let mesh = read_hex_mesh(path, displacement)?;
    mesh.to_lattice()
        .map_err(|e| explain_ghosts(&mesh, e).in_file(path))
}

/// Read a VTK mesh file and recognise it as a uniform or an adaptive body (see
/// [`HexMesh::to_body`]).
pub fn read_body(
    path: impl AsRef<Path>,
    displacement: &DisplacementArray,
) -> Result<MeshBody, IoError> {
    Ok(MeshFile::read(path)?.into_body(displacement)?.body)
}

/// Read a VTK mesh file as an explicit hexahedral mesh, without lattice detection.
pub fn read_hex_mesh(
    path: impl AsRef<Path>,
    displacement: &DisplacementArray,
) -> Result<HexMesh, IoError> {
    MeshFile::read(path)?.into_hex_mesh(displacement)
}

/// A mesh file read whole and parsed, the files of a parallel file's pieces not yet read:
/// [`read_body`] in two steps, for a caller that must know every file a mesh is read from before
/// it reads them.
///
/// A program that writes files compares them with the inputs before any work; the pieces of a
/// `.pvtu` are inputs too, known only once it is read ([`MeshFile::piece_files`]). And each file
/// is read once: a named pipe or a process substitution (`<(zcat mesh.vtu.gz)`) can be read only
/// once.
///
/// ```
/// use cgcontact::{Body, Lattice};
/// use cgcontact::glam::DVec3;
/// use cgcontact_io::{DisplacementArray, MeshFile, MeshFormat, write_mesh};
///
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("block.vtu");
/// write_mesh(&path, &Body::full(Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 1, 1])?), MeshFormat::Xml)?;
/// let file = MeshFile::read(&path)?;
/// assert!(file.piece_files().is_empty()); // a serial file
/// let read = file.into_body(&DisplacementArray::Default)?;
/// assert_eq!(read.point_arrays, ["displacement"]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct MeshFile {
    path: PathBuf,
    parsed: Parsed,
    pieces: Vec<PathBuf>,
}

/// A mesh file read as a body by [`MeshFile::into_body`], and the names of its point arrays.
#[derive(Clone, Debug)]
pub struct MeshRead {
    /// The body, as [`read_body`] reads it.
    pub body: MeshBody,
    /// The point-data number arrays of the file (of every piece of a parallel file), by name,
    /// sorted, each once; legacy names with their `%XX` escapes decoded. String arrays and legacy
    /// id sections are not listed. A caller can name them when the displacement asked for is not
    /// among them, without reading the file again.
    pub point_arrays: Vec<String>,
}

impl MeshFile {
    /// Read the mesh file at `path` whole (within [`crate::max_input_bytes`]) and parse it; a
    /// parallel file's pieces are listed, not read.
    ///
    /// # Errors
    ///
    /// [`IoError`] naming `path` when it cannot be read, is not a VTK file, or fails to parse.
    pub fn read(path: impl AsRef<Path>) -> Result<Self, IoError> {
        let path = path.as_ref();
        let bytes = crate::input::read_input(path, crate::input::Expect::Vtk)?;
        let parsed = parse_file(&bytes).map_err(|e| e.in_file(path))?;
        let pieces = match &parsed.vtk.data {
            DataSet::UnstructuredGrid { pieces, .. } => pieces
                .iter()
                .filter_map(|piece| match piece {
                    Piece::Source(name, _) => Some(piece_path(name, Some(path))),
                    _ => None,
                })
                .collect::<Result<_, _>>()
                .map_err(|e| e.in_file(path))?,
            _ => Vec::new(),
        };
        Ok(Self {
            path: path.to_path_buf(),
            parsed,
            pieces,
        })
    }

    /// The path the file was read from.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The files of a parallel file's pieces, as the file names them, resolved from its folder
    /// (in its order, each as often as it is named); empty for a serial file, whose pieces are
    /// inline.
    #[must_use]
    pub fn piece_files(&self) -> &[PathBuf] {
        &self.pieces
    }

    /// The mesh, its pieces' files read, without lattice detection ([`read_hex_mesh`]).
    ///
    /// # Errors
    ///
    /// [`IoError`] naming the file, and the piece at fault, when the mesh cannot be read.
    pub fn into_hex_mesh(self, displacement: &DisplacementArray) -> Result<HexMesh, IoError> {
        let path = self.path;
        let (mesh, _) = hex_mesh_from_vtk(self.parsed, Some(&path), displacement)
            .map_err(|e| e.in_file(&path))?;
        Ok(mesh)
    }

    /// The mesh, its pieces' files read, recognised as a uniform or an adaptive body
    /// ([`read_body`]), with the names of its point arrays.
    ///
    /// # Errors
    ///
    /// [`IoError`] naming the file, and the piece, cell or node at fault, when the mesh cannot
    /// be read or is not a lattice body.
    pub fn into_body(self, displacement: &DisplacementArray) -> Result<MeshRead, IoError> {
        let path = self.path;
        let (mesh, point_arrays) = hex_mesh_from_vtk(self.parsed, Some(&path), displacement)
            .map_err(|e| e.in_file(&path))?;
        let body = mesh
            .to_body()
            .map_err(|e| explain_ghosts(&mesh, e).in_file(&path))?;
        Ok(MeshRead { body, point_arrays })
    }
}

/// `error`, with a word on ghost cells where it names a ghost copy of `mesh` as overlapping
/// another cell (a copy of the same cell is read as that cell; this one is not the same).
fn explain_ghosts(mesh: &HexMesh, error: ErrorKind) -> ErrorKind {
    // Two copies of one lattice cell are refused only when neither is a ghost
    // (`CellMap::with_ghosts`): an overlap of leaves is what can name one.
    let ErrorKind::OverlappingCells { first, second } = error else {
        return error;
    };
    match [first, second]
        .into_iter()
        .find(|&c| u32::try_from(c).is_ok_and(|c| mesh.ghosts.binary_search(&c).is_ok()))
    {
        Some(ghost) => ErrorKind::GhostCell {
            ghost,
            error: Box::new(error),
        },
        None => error,
    }
}

/// Parse a VTK mesh held in memory (legacy or XML, told from the content).
pub fn parse_hex_mesh(
    bytes: &[u8],
    displacement: &DisplacementArray,
) -> Result<HexMesh, ErrorKind> {
    parse_hex_mesh_impl(bytes, None, displacement)
}

fn parse_hex_mesh_impl(
    bytes: &[u8],
    source: Option<&Path>,
    displacement: &DisplacementArray,
) -> Result<HexMesh, ErrorKind> {
    let parsed = parse_file(bytes)?;
    hex_mesh_from_vtk(parsed, source, displacement).map(|(mesh, _)| mesh)
}

/// A mesh file as parsed, before its pieces are read.
#[derive(Debug)]
struct Parsed {
    vtk: Vtk,
    /// The point arrays each `<Piece>` of an XML file declares (`None` for a legacy file).
    declared: Option<Vec<Vec<DeclaredArray>>>,
    /// The point arrays a parallel file declares for its pieces (`<PPointData>`), by name.
    parallel_point_arrays: Vec<String>,
}

/// Parse the bytes of a mesh file.
fn parse_file(bytes: &[u8]) -> Result<Parsed, ErrorKind> {
    // Every pass over an XML file reads it in the one spelling `xml_normal` gives it.
    let normal = if is_xml(bytes) {
        xml_normal::normalize(bytes)?
    } else {
        None
    };
    let bytes = normal.as_deref().unwrap_or(bytes);
    let vtk = parse_vtk(bytes)?;
    let declared = is_xml(bytes).then(|| declared_point_arrays(bytes));
    Ok(Parsed {
        vtk,
        declared,
        parallel_point_arrays: parallel_point_arrays(bytes),
    })
}

/// The names of the point arrays a parallel file declares for its pieces, in its `<PPointData>`
/// (none for another file). vtkio 0.7.0-rc2 reads `<PPointData>` as holding `<DataArray>`
/// elements, where VTK writes `<PDataArray>`, and so lists none.
fn parallel_point_arrays(xml: &[u8]) -> Vec<String> {
    use crate::raw_appended::{attribute, find};
    let Some(start) = find(xml, b"<PPointData", 0) else {
        return Vec::new();
    };
    let end = find(xml, b"</PPointData", start).unwrap_or(xml.len());
    let mut names = Vec::new();
    let mut at = start;
    while let Some(tag) = find(&xml[..end], b"<PDataArray", at) {
        let close = find(xml, b">", tag).unwrap_or(end);
        if let Some(name) = attribute(&xml[tag..close], b"Name") {
            // Names as vtkio reads a piece's: `xml_normal` leaves `&amp;` and its kind.
            let name = String::from_utf8_lossy(&name).into_owned();
            names.push(quick_xml::escape::unescape(&name).map_or(name.clone(), |n| n.into_owned()));
        }
        at = close;
    }
    names
}

/// Whether the bytes are an XML file (legacy ones start with `# vtk`).
fn is_xml(bytes: &[u8]) -> bool {
    let start = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    start.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'<')
}

/// A point-data array an XML file declares: its name, and its `NumberOfComponents` as written
/// (`None` when absent: VTK then reads one component).
#[derive(Clone, Debug)]
struct DeclaredArray {
    name: String,
    components: Option<String>,
}

/// The point-data arrays each `<Piece>` of an XML file declares, read from the text (pieces of
/// no cell left out, as vtkio never sees them).
///
/// vtkio 0.7.0-rc2 drops a data array whose content fails to decode (a tuple short or long, bad
/// base64, a zlib block of the wrong size, a payload that is not zlib) instead of reporting it:
/// `read_mesh` would then solve the mesh as undeformed. Comparing what the file declares with what
/// vtkio returns turns that into an error. (The fix upstream: `Attribute` decoding in
/// `vtkio::xml` should return its error rather than skip the array.)
fn declared_point_arrays(xml: &[u8]) -> Vec<Vec<DeclaredArray>> {
    use crate::raw_appended::{attribute, find};
    let xml = crate::raw_appended::head(xml);
    let mut pieces = Vec::new();
    let mut at = 0;
    while let Some(start) = find(xml, b"<Piece", at) {
        let tag_end = find(xml, b">", start).unwrap_or(xml.len());
        let piece_end = if xml[..tag_end].ends_with(b"/") {
            tag_end
        } else {
            find(xml, b"</Piece", start).unwrap_or(xml.len())
        };
        at = piece_end.max(start + 1);
        // A piece of no cell is blanked before vtkio reads the file (`without_empty_pieces`):
        // left out here too, so that the lists stay in step with vtkio's pieces.
        if attribute(&xml[start..tag_end], b"NumberOfCells").is_some_and(|v| v.trim_ascii() == b"0")
        {
            continue;
        }
        let piece = &xml[start..piece_end];
        let mut names = Vec::new();
        if let Some(data) = find(piece, b"<PointData", 0) {
            let data_end = find(piece, b"</PointData", data).unwrap_or(piece.len());
            let mut tag_at = data;
            while let Some(tag) = find(&piece[..data_end], b"<DataArray", tag_at) {
                let close = find(piece, b">", tag).unwrap_or(piece.len());
                if let Some(name) = attribute(&piece[tag..close], b"Name") {
                    // Names as vtkio reads them: `xml_normal` leaves `&amp;` and its kind.
                    let name = String::from_utf8_lossy(&name).into_owned();
                    let components = attribute(&piece[tag..close], b"NumberOfComponents")
                        .map(|c| String::from_utf8_lossy(&c).trim().to_owned());
                    names.push(DeclaredArray {
                        name: quick_xml::escape::unescape(&name)
                            .map_or(name.clone(), |n| n.into_owned()),
                        components,
                    });
                }
                tag_at = close;
            }
        }
        pieces.push(names);
    }
    pieces
}

/// Run a vtkio call, turning a panic into an error.
///
/// vtkio 0.7.0-rc2 indexes and unwraps freely on the data it decodes (appended-data offsets, block
/// headers of compressed arrays, `unwrap` in its own conversions), so a truncated or malformed file
/// can panic inside it. Our contract is an error value for any input, so we catch the unwind here;
/// the closure only reads a byte slice and builds a fresh value, so no state is left half-updated.
fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T, ErrorKind>) -> Result<T, ErrorKind> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(panic) => {
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown cause".to_owned());
            Err(ErrorKind::Vtk(format!(
                "{what}: the VTK reader gave up on malformed data ({message})"
            )))
        }
    }
}

/// A vtkio error as ours.
fn vtk_error(what: &str) -> impl FnOnce(vtkio::Error) -> ErrorKind + '_ {
    move |e| ErrorKind::Vtk(format!("{what}: {e}"))
}

/// Parse legacy or XML VTK, told from the first non-blank bytes.
fn parse_vtk(bytes: &[u8]) -> Result<Vtk, ErrorKind> {
    let start = content_start(bytes);
    if start.len() >= 5 && start[..5].eq_ignore_ascii_case(b"# vtk") {
        // Legacy binary files are big-endian by definition of the format.
        guarded("legacy VTK", || {
            // vtkio's parser has no string type and knows no id sections (`GLOBAL_IDS`,
            // `PEDIGREE_IDS`, `EDGE_FLAGS`): those are blanked out first. Nor does it know the
            // types `unsigned_short`, `signed_char`, `vtktypeint64` and `vtktypeuint64`: those
            // are renamed as types it reads to the same values.
            let walk = legacy_sections::walk(bytes);
            let without_strings = match &walk {
                Some(walk) => legacy_strings::blank(bytes, walk)
                    .map_err(|fault| ErrorKind::Vtk(format!("legacy VTK: {fault}")))?,
                None => None,
            };
            let mut text = without_strings.map_or(Cow::Borrowed(bytes), Cow::Owned);
            let renamed = walk
                .as_ref()
                .map(|walk| legacy_types::rename(&mut text, &walk.arrays, walk.binary))
                .unwrap_or_default();
            let blanked = blank_dataset_field(&text);
            let mut vtk = parse_legacy_whole(blanked.as_deref().unwrap_or(&text))?;
            renamed.restore(&mut vtk);
            match ascii_ends_in_a_value(start) {
                Some((line, excerpt)) => {
                    // Lines counted in the file: blank ones before `# vtk` too.
                    let before = bytes[..bytes.len() - start.len()]
                        .iter()
                        .filter(|&&b| b == b'\n')
                        .count();
                    Err(ErrorKind::Vtk(format!(
                        "legacy VTK: line {}: the file ends in {excerpt} with no line end after \
                         it: cut inside its last value? (VTK's writer ends every line; add a \
                         line end if the file is whole)",
                        before + line
                    )))
                }
                None => Ok(vtk),
            }
        })
    } else if start.first() == Some(&b'<') {
        // Another data set is named as such, before its arrays are checked as a grid's would be
        // (a poly data file's empty `Verts` arrays read as a corrupt block header).
        if let Some(other) = other_xml_data_set(bytes) {
            return Err(ErrorKind::NotUnstructuredGrid(other));
        }
        // vtkio is built without LZMA (its `xz2` feature is liblzma, in C): decompress LZMA arrays
        // first and hand it the file uncompressed (see `lzma_arrays`).
        // First what vtkio would skip or misread (an appended array without an offset among
        // them), on the tags as the file has them.
        check_xml_arrays(bytes)?;
        let kept = without_empty_pieces(bytes)?;
        let bytes = kept.as_deref().unwrap_or(bytes);
        // vtkio refuses a polyhedron's face arrays, naming neither the cell nor its type: read
        // without them, the cell is named as a cell of another type, as in a legacy file.
        let without_faces = without_face_arrays(bytes);
        let bytes = without_faces.as_deref().unwrap_or(bytes);
        let decompressed = lzma_arrays::decompress(bytes)?;
        let bytes = decompressed.as_deref().unwrap_or(bytes);
        // vtkio cannot read raw (unencoded) appended data, ParaView's default; re-encode it as base64
        // first (see `raw_appended`).
        let converted = raw_appended::to_base64(bytes)?;
        let xml = converted.as_deref().unwrap_or(bytes);
        // An uncompressed appended array holding more or fewer values than its piece asks for:
        // vtkio reads as many as asked and ignores the rest (see `appended_sizes`).
        crate::appended_sizes::check(xml)?;
        // A corrupt compressed-block header would make vtkio's allocation abort the process.
        let headers = block_headers::check(xml)?;
        // A whole last block, as vtkio would not size it (see `whole_last_blocks`).
        let patched = headers.whole_last_blocks(xml);
        let xml = patched.as_deref().unwrap_or(xml);
        guarded("XML VTK", || {
            Vtk::parse_xml(xml).map_err(|e| {
                use vtkio::xml::{Error as XmlError, ValidationError as Invalid};
                // Errors that name no array, or not the attribute at fault: said in words, with the line.
                let said = match &e {
                    vtkio::Error::XML(XmlError::Validation(Invalid::InvalidDataFormat)) => Some(
                        xml_cells::cell_array_fault(xml, xml_cells::Sought::Uncastable)
                            .unwrap_or_else(|| {
                                "a cell array holds a value no cell array can hold (a \
                                     negative node number or offset, a cell type above 255)"
                                    .to_owned()
                            }),
                    ),
                    vtkio::Error::XML(XmlError::Validation(Invalid::InvalidCellType(t))) => Some(
                        xml_cells::cell_array_fault(xml, xml_cells::Sought::CellType(*t))
                            .unwrap_or_else(|| {
                                format!("the cell array `types` holds {t}: not a VTK cell type")
                            }),
                    ),
                    vtkio::Error::XML(XmlError::Validation(Invalid::DataArraySizeMismatch {
                        name,
                        expected,
                        actual,
                    })) => xml_cells::points_size_fault(xml, name, *expected, *actual),
                    _ => None,
                };
                if let Some(said) = said {
                    return ErrorKind::Vtk(crate::one_line(&format!("XML VTK: {said}")));
                }
                let message = format!("XML VTK: {e}");
                let place = xml_place(xml, &message);
                ErrorKind::Vtk(format!("{message}{place}"))
            })
        })
    } else {
        Err(not_vtk(start))
    }
}

/// `bytes` from their first byte that is not blank, after a UTF-8 byte order mark.
fn content_start(bytes: &[u8]) -> &[u8] {
    let start = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    &start[start
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(start.len())..]
}

/// What a file that starts as neither a legacy nor an XML VTK file is (`start`: its bytes from
/// the first that is not blank).
fn not_vtk(start: &[u8]) -> ErrorKind {
    if start.is_empty() {
        ErrorKind::Format("the file is empty".to_owned())
    } else {
        ErrorKind::Format(
            "neither a legacy VTK file (`# vtk DataFile ...`) nor an XML VTK file (`<VTKFile ...>`)".to_owned(),
        )
    }
}

/// What an XML file holds when its `<VTKFile type>` names a data set of VTK's other than an
/// unstructured grid (serial or parallel); `None` for an unstructured grid, or a type VTK does not
/// write (vtkio's parser then names it).
fn other_xml_data_set(xml: &[u8]) -> Option<&'static str> {
    let start = raw_appended::find(xml, b"<VTKFile", 0)?;
    let end = raw_appended::find(xml, b">", start)?;
    let kind = raw_appended::attribute(&xml[start..end], b"type")?;
    Some(match kind.as_slice() {
        b"ImageData" | b"PImageData" => "image data (.vti)",
        b"PolyData" | b"PPolyData" => "polygonal data (.vtp)",
        b"StructuredGrid" | b"PStructuredGrid" => "a structured grid (.vts)",
        b"RectilinearGrid" | b"PRectilinearGrid" => "a rectilinear grid (.vtr)",
        b"vtkMultiBlockDataSet" => "a multiblock data set (.vtm; give the .vtu of its block)",
        b"vtkPartitionedDataSet" | b"vtkPartitionedDataSetCollection" => {
            "a partitioned data set (.vtpd, .vtpc; give the .vtu of its partition)"
        }
        b"vtkOverlappingAMR" | b"vtkNonOverlappingAMR" | b"vtkHierarchicalBoxDataSet" => {
            "an AMR data set of image blocks (.vthb)"
        }
        b"HyperTreeGrid" => "a hyper tree grid (.htg)",
        _ => return None,
    })
}

/// The VTK XML types of a `<DataArray>`: what `type` may be.
const XML_NUMBER_TYPES: [&str; 10] = [
    "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64", "Float32", "Float64",
];

/// Refuses, in an XML file's pieces, what vtkio would skip without a word and so turn into a
/// mesh read wrong: an element inside an unstructured grid's `<Piece>` other than `PointData`, `CellData`, `Points` and
/// `Cells` (a corrupt `<PointData>` tag drops the displacement), an element inside those four
/// other than `<DataArray>` (a corrupt `<DataArray>` tag drops the array), a data array whose
/// `type` is no VTK type, and cell arrays (`<Cells>`) that are not integers (vtkio truncates a
/// fractional node number). Names the line and the element. Syntax errors are left to vtkio,
/// whose messages `xml_place` locates.
fn check_xml_arrays(xml: &[u8]) -> Result<(), ErrorKind> {
    use quick_xml::events::Event;
    let head = crate::raw_appended::head(xml);
    let mut reader = quick_xml::Reader::from_reader(head);
    let line = |at: u64| crate::raw_appended::line_of(head, at as usize);
    let mut open: Vec<Vec<u8>> = Vec::new();
    loop {
        let at = reader.buffer_position();
        let (tag, empty) = match reader.read_event() {
            Ok(Event::Start(tag)) => (tag, false),
            Ok(Event::Empty(tag)) => (tag, true),
            Ok(Event::End(_)) => {
                open.pop();
                continue;
            }
            Ok(Event::Eof) | Err(_) => return Ok(()),
            Ok(_) => continue,
        };
        let name = tag.name().as_ref().to_vec();
        let shown = |bytes: &[u8]| String::from_utf8_lossy(bytes).into_owned();
        let refuse = |what: String| {
            Err(ErrorKind::Vtk(crate::one_line(&format!(
                "line {}: {what}",
                line(at)
            ))))
        };
        if name == b"DataArray" {
            check_appended_offset(&tag, head.len() < xml.len()).map_err(|what| {
                ErrorKind::Vtk(crate::one_line(&format!("line {}: {what}", line(at))))
            })?;
        }
        xml_cells::check_required(&tag)
            .and_then(|()| xml_cells::check_counts(&tag))
            .map_err(|what| {
                ErrorKind::Vtk(crate::one_line(&format!("line {}: {what}", line(at))))
            })?;
        let parent = open.last().map(Vec::as_slice);
        // Pieces of other data sets (poly data's `Polys`, ...) are refused later, by data set.
        let grid_piece = open.len() >= 2 && open[open.len() - 2] == b"UnstructuredGrid";
        match parent {
            Some(b"Piece")
                if grid_piece
                    && !matches!(
                        name.as_slice(),
                        b"PointData" | b"CellData" | b"Points" | b"Cells"
                    ) =>
            {
                return refuse(format!(
                    "<{}> inside <Piece> is none of PointData, CellData, Points and Cells \
                     (a corrupt tag? its data would be dropped)",
                    shown(&name)
                ));
            }
            Some(within @ (b"PointData" | b"CellData" | b"Points" | b"Cells")) => {
                if name != b"DataArray" {
                    return refuse(format!(
                        "<{}> inside <{}> is not a DataArray (a corrupt tag? its data would be \
                         dropped)",
                        shown(&name),
                        shown(within)
                    ));
                }
                let kind = tag
                    .try_get_attribute("type")
                    .ok()
                    .flatten()
                    .map(|a| a.value.into_owned());
                let array = tag
                    .try_get_attribute("Name")
                    .ok()
                    .flatten()
                    .map_or_else(String::new, |a| format!(" `{}`", shown(&a.value)));
                let numeric = |k: &[u8]| XML_NUMBER_TYPES.iter().any(|t| t.as_bytes() == k);
                let integer =
                    |k: &[u8]| numeric(k) && (k.starts_with(b"Int") || k.starts_with(b"UInt"));
                match kind.as_deref() {
                    Some(k) if within == b"Cells" && !integer(k) => {
                        return refuse(format!(
                            "the cell array{array} is of type {}: cell arrays hold integers",
                            shown(k)
                        ));
                    }
                    Some(k) if !numeric(k) && (within == b"Points" || k != b"String") => {
                        return refuse(format!(
                            "the data array{array} inside <{}> is of type {}, not a VTK number \
                             type",
                            shown(within),
                            shown(k)
                        ));
                    }
                    _ => {}
                }
            }
            _ => {}
        }
        if !empty {
            open.push(name);
        }
    }
}

/// An appended data array must say where its data are: vtkio reads an array without `offset`
/// (or with a misspelt `offzet`) from offset 0, the first array's block, and the mesh was solved
/// with the points as displacements. And the file must have appended data (vtkio's
/// "InvalidDataFormat" named neither the array nor the cause).
fn check_appended_offset(
    tag: &quick_xml::events::BytesStart,
    has_appended_data: bool,
) -> Result<(), String> {
    let value = |name: &str| {
        tag.try_get_attribute(name)
            .ok()
            .flatten()
            .map(|a| a.value.into_owned())
    };
    if value("format").as_deref() != Some(b"appended") {
        return Ok(());
    }
    let array = value("Name").map_or_else(
        || "an unnamed appended data array".to_owned(),
        |n| format!("the appended data array {}", crate::excerpt(&n, 60)),
    );
    if !has_appended_data {
        return Err(format!(
            "{array}: the file has no <AppendedData> to hold it"
        ));
    }
    let offset = value("offset").ok_or_else(|| format!("{array} has no offset attribute"))?;
    let parsed = std::str::from_utf8(&offset)
        .ok()
        .and_then(|o| o.trim().parse::<u64>().ok());
    match parsed {
        Some(_) => Ok(()),
        None => Err(format!(
            "{array}: offset {} is not a byte count",
            crate::excerpt(&offset, 40)
        )),
    }
}

/// Where in an XML file vtkio's error `message` is: the line of the first syntax error, or the line
/// of the data array a validation error names; empty when neither is found. vtkio's errors carry
/// no position.
fn xml_place(xml: &[u8], message: &str) -> String {
    let line_of = |at: usize| {
        1 + xml[..at.min(xml.len())]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    };
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_reader(xml);
    // Open elements: name and where each starts.
    let mut open: Vec<(Vec<u8>, usize)> = Vec::new();
    loop {
        let at = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
        match reader.read_event() {
            Ok(Event::Eof) => {
                if let Some((name, start)) = open.last() {
                    return format!(
                        " (line {}, byte {start}: the file ends inside the <{}> element that starts there: truncated?)",
                        line_of(*start),
                        String::from_utf8_lossy(name)
                    );
                }
                break;
            }
            Ok(Event::Start(tag)) => open.push((tag.name().as_ref().to_vec(), at)),
            Ok(Event::End(_)) => {
                open.pop();
            }
            Ok(_) => {}
            Err(e) => {
                let at = usize::try_from(reader.error_position()).unwrap_or(usize::MAX);
                return format!(" (line {}, byte {at}: {e})", line_of(at));
            }
        }
    }
    // A validation error names an array: `name: "connectivity"`.
    let name = message
        .split("name: \"")
        .nth(1)
        .and_then(|rest| rest.split('"').next());
    if let Some(name) = name {
        let attribute = format!("Name=\"{name}\"");
        if let Some(at) = crate::raw_appended::find(xml, attribute.as_bytes(), 0) {
            return format!(
                " (the data array `{name}` at line {}, byte {at})",
                line_of(at)
            );
        }
    }
    String::new()
}

/// Parse a legacy file with vtkio's parser, refusing input left over after it, and saying on which
/// line the parser stopped.
///
/// `Vtk::parse_legacy_be` drops whatever follows the last section it recognises, so a file cut
/// inside `POINT_DATA` would read as an undeformed mesh, and its errors carry no position; we call
/// the parser it wraps and check both.
fn parse_legacy_whole(bytes: &[u8]) -> Result<Vtk, ErrorKind> {
    let at_line = |rest: &[u8]| {
        let at = bytes.len() - rest.len();
        let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
        let end = rest
            .iter()
            .position(|&b| b == b'\n' || b == b'\r')
            .unwrap_or(rest.len());
        (line, crate::excerpt(&rest[..end], 40))
    };
    match vtkio::parser::parse_be(bytes) {
        Ok((rest, vtk)) => match rest.iter().position(|b| !b.is_ascii_whitespace()) {
            None => match dangling_data_header(bytes) {
                Some((line, header)) => Err(ErrorKind::Vtk(format!(
                    "legacy VTK: line {line}: the file ends after `{header}`, before any of its \
                     arrays (truncated?)"
                ))),
                None => Ok(vtk),
            },
            // Left over: a section the parser stopped in, which the walk may name.
            Some(i) => Err(match legacy_sections::fault(bytes) {
                Some(fault) => ErrorKind::Vtk(format!("legacy VTK: {fault}")),
                None => {
                    let (line, excerpt) = at_line(&rest[i..]);
                    ErrorKind::Vtk(format!(
                        "legacy VTK: line {line}: unexpected {excerpt} after the last complete section (truncated or \
                     malformed section?)"
                    ))
                }
            }),
        },
        // The parser backtracks to the start of the section (or of the file) it could not
        // finish: a walk of the sections against their headers says which one is at fault.
        Err(error) => Err(match legacy_sections::fault(bytes) {
            Some(fault) => ErrorKind::Vtk(format!("legacy VTK: {fault}")),
            // VTK writes an empty grid as `POINTS 0 float` and no cell section at all, which the
            // parser reads as a file cut short.
            None if declares_no_points(bytes) => ErrorKind::NoCells,
            None => match error {
                nom::Err::Incomplete(_) => ErrorKind::Vtk(
                    "legacy VTK: the file ends before its data does (truncated?)".to_owned(),
                ),
                nom::Err::Error(e) | nom::Err::Failure(e)
                    if e.input.iter().all(u8::is_ascii_whitespace) =>
                {
                    // Stopped at the end of the file: nothing there to quote.
                    let (line, _) = at_line(e.input);
                    ErrorKind::Vtk(format!(
                        "legacy VTK: line {line}: the file ends before its data does (truncated, \
                         or a count larger than its values?)"
                    ))
                }
                nom::Err::Error(e) | nom::Err::Failure(e) => {
                    // The parser's own code (`MapOpt`, `Digit`) names its combinator, not the
                    // file's mistake: the line and the text are what a reader can act on.
                    let (line, excerpt) = at_line(e.input);
                    ErrorKind::Vtk(format!(
                        "legacy VTK: line {line}: cannot parse {excerpt} there (an unknown \
                         keyword, cell type or number, or a truncated or malformed section)"
                    ))
                }
            },
        }),
    }
}

/// `xml` with each `<Piece>` of no cell blanked (its bytes made spaces, line ends kept, so that
/// lines and bytes keep their numbers); `None` when every piece has cells; `Err(NoCells)` when
/// none has. VTK writes an empty piece's compressed arrays with no block, which vtkio cannot read
/// (it computes `blocks − 1`), and such a piece adds nothing to the mesh.
fn without_empty_pieces(xml: &[u8]) -> Result<Option<Vec<u8>>, ErrorKind> {
    let (mut at, mut pieces, mut empty) = (0, 0, Vec::new());
    while let Some(start) = raw_appended::find(xml, b"<Piece", at) {
        let Some(tag_end) = raw_appended::find(xml, b">", start) else {
            break;
        };
        let tag = &xml[start..tag_end];
        // The element's end: past `/>`, or past its `</Piece>`.
        let end = if tag.ends_with(b"/") {
            tag_end + 1
        } else {
            match raw_appended::find(xml, b"</Piece>", tag_end) {
                Some(close) => close + b"</Piece>".len(),
                None => break,
            }
        };
        pieces += 1;
        if raw_appended::attribute(tag, b"NumberOfCells").is_some_and(|v| v.trim_ascii() == b"0") {
            empty.push(start..end);
        }
        at = end;
    }
    if empty.is_empty() {
        return Ok(None);
    }
    if empty.len() == pieces {
        return Err(ErrorKind::NoCells);
    }
    let mut blanked = xml.to_vec();
    for range in empty {
        for b in &mut blanked[range] {
            if *b != b'\n' {
                *b = b' ';
            }
        }
    }
    Ok(Some(blanked))
}

/// The cell arrays that describe the faces of polyhedron cells (VTK_POLYHEDRON, type 42): VTK
/// 9.4 and later write `face_connectivity`, `face_offsets`, `polyhedron_to_faces` and
/// `polyhedron_offsets`, earlier versions `faces` and `faceoffsets`.
const FACE_ARRAYS: [&[u8]; 6] = [
    b"face_connectivity",
    b"face_offsets",
    b"polyhedron_to_faces",
    b"polyhedron_offsets",
    b"faces",
    b"faceoffsets",
];

/// `xml` with the face arrays of polyhedron cells ([`FACE_ARRAYS`]) in its `<Cells>` elements
/// blanked (their bytes made spaces, line ends kept); `None` when it has none.
///
/// vtkio reads `<Cells>` only as the three arrays `connectivity`, `offsets` and `types`, and
/// refused a file with polyhedra with "Cells data arrays must contain three DataArrays", naming
/// no cell. Without the face arrays it reads the cells, and the first polyhedron is named with
/// its type, as any cell that is not a hexahedron is (a polyhedron's `connectivity` lists its
/// nodes, as VTK writes it). Their appended blocks, if any, are left unread.
fn without_face_arrays(xml: &[u8]) -> Option<Vec<u8>> {
    use crate::raw_appended::{attribute, find};
    let head = crate::raw_appended::head(xml);
    let end = head.len();
    let mut faces = Vec::new();
    let mut at = 0;
    while let Some(cells) = find(head, b"<Cells", at) {
        let cells_end = find(head, b"</Cells>", cells).unwrap_or(end);
        at = cells_end.max(cells + 1);
        let mut array_at = cells;
        while let Some(start) = find(&head[..cells_end], b"<DataArray", array_at) {
            let tag_end = find(head, b">", start).unwrap_or(cells_end);
            let tag = &head[start..tag_end];
            let array_end = if tag.ends_with(b"/") {
                tag_end + 1
            } else {
                find(head, b"</DataArray>", tag_end)
                    .map_or(cells_end, |e| e + b"</DataArray>".len())
            };
            array_at = array_end.max(start + 1);
            if attribute(tag, b"Name").is_some_and(|name| FACE_ARRAYS.contains(&name.as_slice())) {
                faces.push(start..array_end.min(cells_end));
            }
        }
    }
    if faces.is_empty() {
        return None;
    }
    let mut blanked = xml.to_vec();
    for range in faces {
        for b in &mut blanked[range] {
            if *b != b'\n' {
                *b = b' ';
            }
        }
    }
    Some(blanked)
}

/// Whether a legacy file's `POINTS` line declares no point.
fn declares_no_points(bytes: &[u8]) -> bool {
    bytes.split(|&b| b == b'\n').any(|line| {
        let mut words = line.trim_ascii().split(|b| b.is_ascii_whitespace());
        words.next() == Some(b"POINTS".as_slice()) && words.next() == Some(b"0".as_slice())
    })
}

/// A legacy file whose data set's own field data (a `FIELD` block right after the `DATASET`
/// line, where VTK's writer puts `TimeValue` and the like) is blanked out: each of its bytes but
/// line ends made a space, so that lines keep their numbers. `None` when the file has no such
/// block, or one vtkio cannot parse (its parser then names the line).
///
/// vtkio 0.7.0-rc2 reads `FIELD` only as point or cell data, or as a whole data set. Its own
/// parser measures the block: the header lines followed by the block read as a `FIELD` data
/// set, and what it leaves over is the rest of the file.
fn blank_dataset_field(bytes: &[u8]) -> Option<Vec<u8>> {
    let line_end = |from: usize| {
        bytes[from..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|i| from + i + 1)
    };
    // The header: `# vtk DataFile ...`, the title, ASCII or BINARY.
    let mut header_end = 0;
    for _ in 0..3 {
        header_end = line_end(header_end)?;
    }
    let skip_blank = |from: usize| {
        from + bytes[from..]
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(bytes.len() - from)
    };
    let dataset = skip_blank(header_end);
    let starts_with = |at: usize, word: &[u8]| {
        bytes.len() >= at + word.len() && bytes[at..at + word.len()].eq_ignore_ascii_case(word)
    };
    if !starts_with(dataset, b"DATASET") {
        return None;
    }
    let field = skip_blank(line_end(dataset)?);
    if !starts_with(field, b"FIELD") || !bytes.get(field + 5)?.is_ascii_whitespace() {
        return None;
    }
    let alone = [&bytes[..header_end], &bytes[field..]].concat();
    let (rest, _) = vtkio::parser::parse_be(&alone).ok()?;
    let end = field + (alone.len() - header_end) - rest.len();
    let mut blanked = bytes.to_vec();
    for byte in &mut blanked[field..end] {
        if *byte != b'\n' && *byte != b'\r' {
            *byte = b' ';
        }
    }
    Some(blanked)
}

/// The last line of a legacy file, with its number, when it is a data section's header with no
/// array after it that no writer ends a whole file with; vtkio reads such a section as one
/// without arrays, so a file cut right after the header would read as a mesh without
/// displacement.
/// - `POINT_DATA n`: VTK writes the header only before an array, and vtkio (our own writer)
///   follows it with `CELL_DATA`.
/// - `CELL_DATA n` with no `POINT_DATA` line before it: vtkio ends its files with a bare
///   `CELL_DATA` after its `POINT_DATA` section, and VTK writes `CELL_DATA` before `POINT_DATA`
///   and only before an array.
fn dangling_data_header(bytes: &[u8]) -> Option<(usize, String)> {
    let end = bytes.iter().rposition(|b| !b.is_ascii_whitespace())? + 1;
    let start = bytes[..end]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    let line = std::str::from_utf8(&bytes[start..end]).ok()?;
    let mut words = line.split_whitespace();
    let keyword = words.next()?.to_ascii_uppercase();
    let count: u64 = words.next()?.parse().ok()?;
    if count == 0 || words.next().is_some() {
        return None;
    }
    let point_data_before = || {
        bytes[..start]
            .windows(12)
            .any(|w| w.eq_ignore_ascii_case(b"\nPOINT_DATA "))
    };
    let dangling = match keyword.as_str() {
        "POINT_DATA" => true,
        "CELL_DATA" => !point_data_before(),
        _ => false,
    };
    dangling.then(|| {
        let number = 1 + bytes[..start].iter().filter(|&&b| b == b'\n').count();
        (number, line.trim().to_owned())
    })
}

/// In an ASCII legacy file `bytes` (from its `# vtk` line) whose last byte is not whitespace, the
/// last line's number and an excerpt of its last word; `None` otherwise. A file cut inside its
/// last number (`0.123456` cut to `0.12`) still parses, each count whole, into another value:
/// only the missing line end tells, since VTK's writer ends every line, the last included.
fn ascii_ends_in_a_value(bytes: &[u8]) -> Option<(usize, String)> {
    let format = bytes.split(|&b| b == b'\n').nth(2)?;
    if !format.trim_ascii().eq_ignore_ascii_case(b"ASCII") || bytes.last()?.is_ascii_whitespace() {
        return None;
    }
    let word = bytes
        .iter()
        .rposition(u8::is_ascii_whitespace)
        .map_or(0, |i| i + 1);
    let line = 1 + bytes.iter().filter(|&&b| b == b'\n').count();
    Some((line, crate::excerpt(&bytes[word..], 40)))
}

/// Extract points, hexahedra and the displacement array from a parsed file, and the names of its
/// point arrays (sorted, each once).
fn hex_mesh_from_vtk(
    parsed: Parsed,
    source: Option<&Path>,
    displacement: &DisplacementArray,
) -> Result<(HexMesh, Vec<String>), ErrorKind> {
    let declared = parsed.declared.as_deref();
    let pieces = match parsed.vtk.data {
        DataSet::UnstructuredGrid { pieces, .. } => pieces,
        DataSet::ImageData { .. } => {
            return Err(ErrorKind::NotUnstructuredGrid(
                "image data (STRUCTURED_POINTS)",
            ));
        }
        DataSet::StructuredGrid { .. } => {
            return Err(ErrorKind::NotUnstructuredGrid("a structured grid"));
        }
        DataSet::RectilinearGrid { .. } => {
            return Err(ErrorKind::NotUnstructuredGrid("a rectilinear grid"));
        }
        DataSet::PolyData { .. } => {
            return Err(ErrorKind::NotUnstructuredGrid("polygonal data (POLYDATA)"));
        }
        DataSet::Field { .. } => {
            return Err(ErrorKind::NotUnstructuredGrid("a field (no geometry)"));
        }
    };
    let mut mesh = HexMesh::default();
    let mut u: Option<Vec<DVec3>> = match displacement {
        DisplacementArray::Ignore => None,
        _ => Some(Vec::new()),
    };
    let mut found_any = false;
    // The first piece with the displacement and the first without it: a file with both is refused.
    let (mut with, mut without) = (None, None);
    let mut available = Vec::new();
    // A parallel file's pieces are files of their own, each read and checked as a serial file is;
    // a serial file's pieces are inline. Either way, one list of pieces in order.
    let mut loaded = Vec::with_capacity(pieces.len());
    // Each piece file's identity (its canonical path) and the piece that first named it: a file
    // named twice would hold every one of its cells twice, and read again and again it could
    // exhaust memory before any check (a short parallel file naming one large piece many times).
    let mut files = std::collections::HashMap::new();
    for (index, piece) in pieces.into_iter().enumerate() {
        match piece {
            Piece::Source(name, _) => {
                let file = piece_path(&name, source)?;
                let in_piece = |error| ErrorKind::Piece {
                    piece: index,
                    file: file.clone(),
                    error: Box::new(error),
                };
                if let Ok(canonical) = std::fs::canonicalize(&file)
                    && let Some(first) = files.insert(canonical, index)
                {
                    return Err(in_piece(ErrorKind::Parallel(format!(
                        "the file of piece {first} again: each piece file holds cells of its \
                         own, and would hold them twice"
                    ))));
                }
                let (pieces, declared) = read_source_piece(&file).map_err(in_piece)?;
                for (at, piece) in pieces.into_iter().enumerate() {
                    loaded.push(LoadedPiece {
                        piece,
                        declared: declared.get(at).cloned(),
                        file: Some((index, file.clone())),
                    });
                }
            }
            inline => loaded.push(LoadedPiece {
                piece: guarded("piece", || {
                    inline
                        .into_loaded_piece_data(None)
                        .map_err(|e| vtk_error("piece")(e.into()))
                })?,
                declared: declared.and_then(|d| d.get(index)).map(|d| d.to_vec()),
                file: None,
            }),
        }
    }
    for (index, loaded) in loaded.into_iter().enumerate() {
        let in_piece = |error| match &loaded.file {
            Some((piece, file)) => ErrorKind::Piece {
                piece: *piece,
                file: file.clone(),
                error: Box::new(error),
            },
            None => error,
        };
        let label = match &loaded.file {
            Some((piece, file)) => format!("piece {piece} ({})", file.display()),
            None => format!("piece {index}"),
        };
        let piece = &loaded.piece;
        let first_node = mesh.points.len();
        let first_cell = mesh.cells.len();
        let points = piece_points(piece).map_err(in_piece)?;
        mesh.points.extend_from_slice(&points);
        append_cells(piece, first_node, first_cell, points.len(), &mut mesh.cells)
            .map_err(in_piece)?;
        let ghosts = ghost_cells(piece, mesh.cells.len() - first_cell).map_err(in_piece)?;
        mesh.ghosts
            .extend(ghosts.into_iter().map(|c| (first_cell + c) as u32));
        let legacy = declared.is_none() && loaded.file.is_none();
        available.extend(point_array_names(piece, legacy));
        if let Some(u) = &mut u {
            match piece_displacement(piece, displacement, points.len(), legacy).map_err(in_piece)? {
                Some(values) => {
                    found_any = true;
                    with.get_or_insert(label);
                    u.extend(values);
                }
                None => {
                    let wanted = match displacement {
                        DisplacementArray::Named(name) => name.as_str(),
                        _ => DEFAULT_DISPLACEMENT,
                    };
                    let in_file = (loaded.declared.as_ref())
                        .and_then(|arrays| arrays.iter().find(|a| a.name == wanted));
                    if let Some(array) = in_file {
                        // vtkio drops an array whose values are not its tuples × components: with
                        // other than 3 components, that is the first thing to name.
                        let message = match array.components.as_deref() {
                            Some("3") => format!(
                                "{label} declares it, but its data cannot be decoded (a \
                                 length that does not match the node count, corrupt base64 or \
                                 compressed data, or an empty appended block)"
                            ),
                            Some(c) => format!(
                                "{label} declares it with NumberOfComponents=\"{}\", and \
                                 a displacement has 3 components per node",
                                crate::excerpt(c.as_bytes(), 20).trim_matches('`')
                            ),
                            None => format!(
                                "{label} declares it without NumberOfComponents (1 \
                                 component per node, as VTK reads it), and a displacement has \
                                 3 components per node"
                            ),
                        };
                        return Err(ErrorKind::BadDisplacement {
                            name: wanted.to_owned(),
                            message,
                        });
                    }
                    without.get_or_insert(label);
                    u.extend(std::iter::repeat_n(DVec3::ZERO, points.len()));
                }
            }
        }
    }
    if let (Some(with), Some(without)) = (with, &without) {
        // Its nodes would be read as undeformed, while the other pieces' move.
        return Err(ErrorKind::BadDisplacement {
            name: match displacement {
                DisplacementArray::Named(name) => name.clone(),
                _ => DEFAULT_DISPLACEMENT.to_owned(),
            },
            message: format!(
                "{without} has no such point array, but {with} has one: every piece \
                 must carry the displacement of its nodes"
            ),
        });
    }
    available.sort();
    available.dedup();
    // A parallel file that declares the displacement in its `<PPointData>`, read from pieces of
    // which none carries it: its nodes would be read as undeformed.
    if let (Some(without), false) = (&without, found_any) {
        let wanted = match displacement {
            DisplacementArray::Named(name) => name.as_str(),
            _ => DEFAULT_DISPLACEMENT,
        };
        if parsed.parallel_point_arrays.iter().any(|a| a == wanted) {
            return Err(ErrorKind::BadDisplacement {
                name: wanted.to_owned(),
                message: format!(
                    "the parallel file declares it in its <PPointData>, but no piece has it \
                     ({without} has no such point array, nor has any other): its nodes would \
                     be read as undeformed"
                ),
            });
        }
    }
    if let DisplacementArray::Named(name) = displacement
        && !found_any
    {
        let available = if available.is_empty() {
            "none".to_owned()
        } else {
            available.join(", ")
        };
        return Err(ErrorKind::MissingDisplacement {
            name: name.clone(),
            available,
        });
    }
    mesh.displacement = if found_any { u } else { None };
    if mesh.cells.is_empty() {
        return Err(ErrorKind::NoCells);
    }
    // One rule for every format: a NaN or infinity anywhere in the nodes or the displacement is an
    // error, used node or not (a legacy ASCII parser cannot read `nan` at all; a binary or XML file
    // could carry one anywhere).
    if let Some(node) = mesh.points.iter().position(|p| !p.is_finite()) {
        return Err(ErrorKind::NonFiniteNode {
            node,
            position: mesh.points[node].to_array(),
        });
    }
    if let Some(u) = &mesh.displacement
        && let Some(node) = u.iter().position(|v| !v.is_finite())
    {
        return Err(ErrorKind::NonFiniteDisplacement {
            node,
            value: u[node].to_array(),
        });
    }
    Ok((mesh, available))
}

/// One piece of a mesh file: inline in it, or read from a parallel file's piece file.
struct LoadedPiece {
    piece: UnstructuredGridPiece,
    /// The point-data arrays its XML declares (`None` in a legacy file).
    declared: Option<Vec<DeclaredArray>>,
    /// For a parallel file's piece: its index there and its file.
    file: Option<(usize, PathBuf)>,
}

/// The file of a parallel file's piece `name`: relative to the parallel file's folder unless it
/// is absolute, as VTK's reader resolves it.
fn piece_path(name: &str, source: Option<&Path>) -> Result<PathBuf, ErrorKind> {
    let Some(source) = source else {
        return Err(ErrorKind::Parallel(
            "a parallel file (PUnstructuredGrid) names its pieces' files relative to its own \
             folder: read it from its path, not from memory"
                .to_owned(),
        ));
    };
    let name = Path::new(name);
    Ok(if name.has_root() {
        name.to_path_buf()
    } else {
        source.parent().unwrap_or(Path::new("")).join(name)
    })
}

/// The inline pieces of a parallel file's piece `file`, with the point-data arrays each declares,
/// read and checked as a mesh file of its own is: within the input size limit, and only an XML
/// unstructured grid with its data inline or appended (a piece is no parallel file). A piece of
/// no cell gives no piece.
fn read_source_piece(
    file: &Path,
) -> Result<(Vec<UnstructuredGridPiece>, Vec<Vec<DeclaredArray>>), ErrorKind> {
    let bytes =
        crate::input::read_input(file, crate::input::Expect::Vtk).map_err(IoError::into_kind)?;
    if !is_xml(&bytes) {
        let start = content_start(&bytes);
        // Only a file that starts as one is called legacy: an empty piece file, or one cut
        // inside its first bytes (a parallel write that failed), is said to be what it is.
        if !(start.len() >= 5 && start[..5].eq_ignore_ascii_case(b"# vtk")) {
            return Err(not_vtk(start));
        }
        return Err(ErrorKind::Parallel(
            "a legacy VTK file: the pieces of a parallel file are XML unstructured grids (.vtu)"
                .to_owned(),
        ));
    }
    let normal = xml_normal::normalize(&bytes)?;
    let bytes = normal.as_deref().unwrap_or(&bytes);
    let vtk = match parse_vtk(bytes) {
        Err(ErrorKind::NoCells) => return Ok((Vec::new(), Vec::new())),
        parsed => parsed?,
    };
    let declared = declared_point_arrays(bytes);
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return Err(ErrorKind::Parallel(
            "not an unstructured grid: the pieces of a parallel file of unstructured grids are \
             unstructured grids (.vtu)"
                .to_owned(),
        ));
    };
    let mut inline = Vec::with_capacity(pieces.len());
    for piece in pieces {
        match piece {
            Piece::Inline(piece) => inline.push(*piece),
            _ => {
                return Err(ErrorKind::Parallel(
                    "a parallel file (PUnstructuredGrid) itself: the pieces of a parallel file \
                     are serial .vtu files"
                        .to_owned(),
                ));
            }
        }
    }
    Ok((inline, declared))
}

/// The cells of `piece` (0-based in it) that a `vtkGhostType` cell array flags as duplicates
/// (bit 1), whether the array is a data array (XML, legacy `SCALARS`) or in a legacy `FIELD`; an
/// array of another length than the piece's `cells` is an error (its flags would fall on the
/// next piece's cells).
fn ghost_cells(piece: &UnstructuredGridPiece, cells: usize) -> Result<Vec<usize>, ErrorKind> {
    const NAME: &str = "vtkGhostType";
    const DUPLICATE_CELL: u64 = 1;
    let array = piece
        .data
        .cell
        .iter()
        .find_map(|attribute| match attribute {
            Attribute::DataArray(array) if array.name == NAME => Some(&array.data),
            Attribute::Field { data_array, .. } => {
                data_array.iter().find(|a| a.name == NAME).map(|a| &a.data)
            }
            Attribute::DataArray(_) => None,
        });
    let Some(array) = array else {
        return Ok(Vec::new());
    };
    let flags = array.cast_into::<f64>().unwrap_or_default();
    if flags.len() != cells {
        return Err(ErrorKind::Topology(format!(
            "the cell array {NAME} holds {} values for {cells} cells",
            flags.len()
        )));
    }
    Ok(flags
        .iter()
        .enumerate()
        .filter(|&(_, &f)| f >= 0.0 && (f as u64) & DUPLICATE_CELL != 0)
        .map(|(cell, _)| cell)
        .collect())
}

fn piece_points(piece: &UnstructuredGridPiece) -> Result<Vec<DVec3>, ErrorKind> {
    let values: Vec<f64> = piece.points.cast_into::<f64>().ok_or_else(|| {
        ErrorKind::Points(format!(
            "coordinates of type {:?} are not numbers",
            piece.points.scalar_type()
        ))
    })?;
    if values.len() % 3 != 0 {
        return Err(ErrorKind::Points(format!(
            "{} coordinate values is not a multiple of 3",
            values.len()
        )));
    }
    if values.len() / 3 > u32::MAX as usize {
        return Err(ErrorKind::Points(format!(
            "{} nodes exceed the 2^32 this library indexes",
            values.len() / 3
        )));
    }
    Ok(values
        .chunks_exact(3)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect())
}

/// Hexahedron corner order of a VTK_VOXEL (type 11) in VTK hexahedron order: a voxel numbers its
/// corners x fastest, then y, then z, so corners 2/3 and 6/7 swap.
const VOXEL_TO_HEX: [usize; 8] = [0, 1, 3, 2, 4, 5, 7, 6];

/// The cells of one piece, as 8 node indices each (offset by the nodes of earlier pieces).
fn append_cells(
    piece: &UnstructuredGridPiece,
    first_node: usize,
    first_cell: usize,
    point_count: usize,
    out: &mut Vec<[u32; 8]>,
) -> Result<(), ErrorKind> {
    let types = &piece.cells.types;
    let total_points = first_node + point_count;
    // Node lists per cell, as (start, end) into a flat list, whatever the layout.
    let (flat, ranges): (Vec<u64>, Vec<(usize, usize)>) = match &piece.cells.cell_verts {
        VertexNumbers::Legacy {
            num_cells,
            vertices,
        } => {
            // The count comes from the file: reserve no more than the list can hold.
            let mut ranges = Vec::with_capacity((*num_cells as usize).min(vertices.len()));
            let mut at = 0usize;
            for c in 0..*num_cells as usize {
                let Some(&n) = vertices.get(at) else {
                    return Err(ErrorKind::Topology(format!(
                        "CELLS declares {num_cells} cells but its list ends at cell {}",
                        first_cell + c
                    )));
                };
                let end = at + 1 + n as usize;
                if end > vertices.len() {
                    return Err(ErrorKind::Topology(format!(
                        "cell {}: {n} nodes run past the end of the CELLS list",
                        first_cell + c
                    )));
                }
                ranges.push((at + 1, end));
                at = end;
            }
            if at != vertices.len() {
                return Err(ErrorKind::Topology(format!(
                    "CELLS holds {} values, {} more than its {num_cells} cells use",
                    vertices.len(),
                    vertices.len() - at
                )));
            }
            (vertices.iter().map(|&v| u64::from(v)).collect(), ranges)
        }
        VertexNumbers::XML {
            connectivity,
            offsets,
        } => {
            // Offsets are cell ends; legacy 5.x files and some writers add a leading 0.
            let ends = match offsets.split_first() {
                Some((&0, rest)) if offsets.len() == types.len() + 1 => rest,
                Some((&first, _)) if offsets.len() == types.len() + 1 => {
                    return Err(ErrorKind::Topology(format!(
                        "{} offsets for {} cells start at {first}: a list of cell starts and \
                         the end (legacy 5.x OFFSETS) starts at 0",
                        offsets.len(),
                        types.len()
                    )));
                }
                _ => offsets.as_slice(),
            };
            let mut ranges = Vec::with_capacity(ends.len());
            let mut start = 0usize;
            for (c, &end) in ends.iter().enumerate() {
                let end = usize::try_from(end).unwrap_or(usize::MAX);
                if end < start || end > connectivity.len() {
                    return Err(ErrorKind::Topology(format!(
                        "cell {}: offset {end} is outside the connectivity array (length {}, previous offset {start})",
                        first_cell + c,
                        connectivity.len()
                    )));
                }
                ranges.push((start, end));
                start = end;
            }
            (connectivity.clone(), ranges)
        }
    };
    if ranges.len() != types.len() {
        return Err(ErrorKind::Topology(format!(
            "{} cells in the connectivity but {} cell types",
            ranges.len(),
            types.len()
        )));
    }
    out.reserve(ranges.len());
    for (c, (&(start, end), &kind)) in ranges.iter().zip(types).enumerate() {
        let cell = first_cell + c;
        let order: &[usize; 8] = match kind {
            CellType::Hexahedron => &[0, 1, 2, 3, 4, 5, 6, 7],
            CellType::Voxel => &VOXEL_TO_HEX,
            other => {
                return Err(ErrorKind::NotHexahedron {
                    cell,
                    vtk_type: other as u8,
                    name: format!("{other:?}"),
                });
            }
        };
        let nodes = &flat[start..end];
        if nodes.len() != 8 {
            return Err(ErrorKind::Topology(format!(
                "cell {cell}: a hexahedron with {} nodes, expected 8",
                nodes.len()
            )));
        }
        let mut hex = [0u32; 8];
        for (corner, &from) in order.iter().enumerate() {
            let node = nodes[from];
            if node >= point_count as u64 {
                return Err(ErrorKind::MissingNode {
                    cell,
                    node,
                    points: total_points,
                });
            }
            hex[corner] = (first_node as u64 + node) as u32;
        }
        out.push(hex);
    }
    Ok(())
}

/// A point array's name as VTK's reader knows it: VTK's legacy writer stores a name with `%XX`
/// for spaces and other bytes; its reader decodes them, and so do we, so that `my displacement`
/// is found as VTK finds it.
fn array_name(name: &str, legacy: bool) -> String {
    if legacy {
        decode_legacy_name(name)
    } else {
        name.to_owned()
    }
}

/// The names of the point arrays of one piece (`legacy`: of a legacy file), in its order.
fn point_array_names(piece: &UnstructuredGridPiece, legacy: bool) -> Vec<String> {
    let mut names = Vec::new();
    for attribute in &piece.data.point {
        match attribute {
            Attribute::DataArray(array) => names.push(array_name(&array.name, legacy)),
            Attribute::Field { data_array, .. } => names.extend(
                data_array
                    .iter()
                    .map(|array| array_name(&array.name, legacy)),
            ),
        }
    }
    names
}

/// The displacement array of one piece, if it has the one asked for.
fn piece_displacement(
    piece: &UnstructuredGridPiece,
    which: &DisplacementArray,
    point_count: usize,
    legacy: bool,
) -> Result<Option<Vec<DVec3>>, ErrorKind> {
    let name = match which {
        DisplacementArray::Default => DEFAULT_DISPLACEMENT,
        DisplacementArray::Named(n) => n.as_str(),
        DisplacementArray::Ignore => return Ok(None),
    };
    // Arrays come as attributes (VECTORS, SCALARS, XML DataArray) or inside FIELD blocks.
    let mut found = Vec::new();
    for attribute in &piece.data.point {
        match attribute {
            Attribute::DataArray(array) => {
                if array_name(&array.name, legacy) == name {
                    found.push((array.elem.num_comp() as usize, &array.data));
                }
            }
            Attribute::Field { data_array, .. } => {
                for array in data_array {
                    if array_name(&array.name, legacy) == name {
                        found.push((array.elem as usize, &array.data));
                    }
                }
            }
        }
    }
    let bad = |message: String| ErrorKind::BadDisplacement {
        name: name.to_owned(),
        message,
    };
    let (components, data) = match found.as_slice() {
        [] => return Ok(None),
        [one] => *one,
        more => {
            return Err(bad(format!(
                "{} point arrays have that name: which one is the displacement is ambiguous",
                more.len()
            )));
        }
    };
    if components != 3 {
        let plural = if components == 1 { "" } else { "s" };
        return Err(bad(format!(
            "{components} component{plural} per node, expected 3"
        )));
    }
    let values: Vec<f64> = data.cast_into::<f64>().ok_or_else(|| {
        bad(format!(
            "values of type {:?} are not numbers",
            data.scalar_type()
        ))
    })?;
    if values.len() != 3 * point_count {
        return Err(bad(format!(
            "{} values for {point_count} nodes, expected {}",
            values.len(),
            3 * point_count
        )));
    }
    let u: Vec<DVec3> = values
        .chunks_exact(3)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect();
    Ok(Some(u))
}

/// A legacy VTK array name with its `%XX` escapes decoded, as `vtkDataReader::DecodeString` does:
/// `%` and two hexadecimal digits stand for that byte; any other `%` is kept.
fn decode_legacy_name(name: &str) -> String {
    let bytes = name.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut k = 0;
    while k < bytes.len() {
        let hex = bytes
            .get(k + 1..k + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .filter(|h| h.bytes().all(|b| b.is_ascii_hexdigit()))
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match hex {
            Some(byte) if bytes[k] == b'%' => {
                out.push(byte);
                k += 3;
            }
            _ => {
                out.push(bytes[k]);
                k += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::decode_legacy_name;

    #[test]
    fn legacy_names_are_percent_decoded_as_vtk_does() {
        assert_eq!(decode_legacy_name("my%20displacement"), "my displacement");
        assert_eq!(decode_legacy_name("a%25b%2"), "a%b%2");
        assert_eq!(decode_legacy_name("%zz%4A"), "%zzJ");
    }
}
