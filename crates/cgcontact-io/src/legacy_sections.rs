//! Which section of a legacy VTK file is at fault, for when vtkio's parser gives up on it.
//!
//! vtkio's legacy parser backtracks to the start of a section it cannot finish (often to line 1,
//! `# vtk DataFile Version 4.2`) and its errors carry no position. So when it fails, the sections
//! are walked here against their headers, and the first one at fault is named with its line:
//! - a count that overflows 64 bits (`POINTS 12297829382473034438 double`: 3 × n values);
//! - a `POINT_DATA n` or `CELL_DATA n` that is not the file's node or cell count;
//! - in an ASCII file, a section holding fewer values than its header declares (counted);
//! - in a binary file, a section whose bytes run past the end of the file (`POINTS 4000000000
//!   double` in a file of 4 KB), or end where no header follows (`POINTS 27 double` over the
//!   bytes of 26 or 28 nodes).
//!
//! The same walk finds what vtkio's parser cannot read and the reader never needs, for
//! `legacy_strings` to blank out before it parses:
//! - the string arrays of `FIELD` blocks (`name components tuples string`);
//! - the `GLOBAL_IDS name type`, `PEDIGREE_IDS name type` and `EDGE_FLAGS name type` sections of
//!   point and cell data (edge flags of point data only, as VTK reads them), one value a node or
//!   cell, of any type VTK writes there: its number types (`vtkIdType` is written as 4-byte
//!   integers), `bit` (binary: packed 8 a byte; ASCII: one number each), `string` and `variant` (text lines, `type value`, in binary files
//!   too);
//! - the `TENSORS6 name type` sections (symmetric tensors, six values a node or cell), measured
//!   as id sections are.
//!
//! Such an array or section that does not hold what it declares is a fault (cut, a length past the
//! end of the file, an ASCII count above or below its values or strings, binary values or strings
//! that do not end at VTK's line end, a string array of other tuples than its section's nodes or
//! cells, an array after it with other tuples: where a wrong length lands the walk). The walk
//! measures them as VTK's reader reads them (`vtkDataReader::ReadArray`): numbers and variants as
//! words, over any lines; strings in an ASCII file one a line, percent-encoded by the writer so
//! that they hold no whitespace (an empty string is an empty line); in a binary file each
//! string's bytes after a big-endian length whose first two bits give its width (`11`: 6 bits in
//! 1 byte, `10`: 14 bits in 2, `01`: 30 bits in 4, `00`: 64 bits in 8). A `METADATA` block (text,
//! up to an empty line, in either kind of file) is skipped, and belongs to the array or section it
//! follows.

use std::ops::Range;

/// A section's header line (trimmed), its 1-based number and the byte its text starts at.
#[derive(Clone, Copy)]
pub(crate) struct Header<'a> {
    pub(crate) line: usize,
    pub(crate) at: usize,
    pub(crate) text: &'a str,
}

/// What vtkio's parser cannot read and the reader never needs, as a walk measured it.
pub(crate) struct Unread<'a> {
    /// Where it is.
    pub(crate) within: Within<'a>,
    /// Its bytes: from its header line to the end of its values, or of the `METADATA` block
    /// after them.
    pub(crate) span: Range<usize>,
}

/// Where an unread array is.
#[derive(Clone, Copy)]
pub(crate) enum Within<'a> {
    /// A string array of the `FIELD` block with this header line (`FIELD name n`, exactly these
    /// words), which declares `arrays` arrays.
    Field { header: Header<'a>, arrays: u64 },
    /// A section of point or cell data of its own, with this header line: `GLOBAL_IDS name
    /// type`, `PEDIGREE_IDS name type` or `EDGE_FLAGS name type`.
    Attribute(Header<'a>),
}

/// The first section at fault: `line N: what is wrong`, and whether it is in what the walk
/// measures for blanking (a string array or an id section), and whether it is a fault even in a
/// file vtkio's parser reads whole.
pub(crate) struct Fault {
    pub(crate) message: String,
    pub(crate) in_unread: bool,
    /// A `POINT_DATA n` or `CELL_DATA n` that is not the file's node or cell count: vtkio's
    /// parser reads the arrays after it by their own lengths and never compares the two, so such
    /// a file parses (a `POINT_DATA 1` before a displacement of every node).
    pub(crate) unparsed_count: bool,
}

impl Fault {
    fn section(message: String) -> Self {
        Self {
            message,
            in_unread: false,
            unparsed_count: false,
        }
    }

    fn unread(message: String) -> Self {
        Self {
            message,
            in_unread: true,
            unparsed_count: false,
        }
    }
}

/// What a walk of a legacy file's sections found: the string arrays of its `FIELD` blocks and its
/// id sections up to the first fault, or to the first line the walk does not know in a binary
/// file (after which it cannot tell data from headers).
#[derive(Default)]
pub(crate) struct Walk<'a> {
    pub(crate) unread: Vec<Unread<'a>>,
    pub(crate) fault: Option<Fault>,
    /// The number arrays of point, cell and field data met, in file order: each `SCALARS`,
    /// `VECTORS` and `NORMALS` section and each array of a `FIELD` block.
    pub(crate) arrays: Vec<Array<'a>>,
    /// Whether the file is binary (its third line `BINARY`), not ASCII.
    pub(crate) binary: bool,
}

/// A number array of point, cell or field data, as its header declares it.
#[derive(Clone, Copy)]
pub(crate) struct Array<'a> {
    /// Its name, as written (`%XX` escapes not decoded).
    pub(crate) name: &'a str,
    /// Its type word, as written, and the byte it starts at.
    pub(crate) kind: &'a str,
    pub(crate) kind_at: usize,
    /// The `POINT_DATA n` or `CELL_DATA n` header of its section; `None` for the data set's own
    /// field data (a `FIELD` block before any of them).
    pub(crate) of: Option<Header<'a>>,
}

/// A `FIELD name n` block: its header, its arrays, and how many of them the walk has met.
#[derive(Clone, Copy)]
struct FieldBlock<'a> {
    header: Header<'a>,
    arrays: u64,
    met: u64,
}

/// What the headers read so far declare.
#[derive(Default)]
struct Declared<'a> {
    /// `POINTS n`: the node count.
    points: Option<(u64, Header<'a>)>,
    /// `CELL_TYPES n`: the cell count.
    cell_types: Option<(u64, Header<'a>)>,
    /// `CELLS n size`.
    cells: (u64, u64),
    /// The tuples of each array of the current `POINT_DATA` or `CELL_DATA` section.
    tuples: u64,
    /// That section's header, once one is met: the arrays of its `FIELD` blocks hold one tuple
    /// per node or cell.
    attributes: Option<Header<'a>>,
    /// The string array or id section just measured: a header must follow it (the walks set it;
    /// the next header read clears it).
    after_unread: Option<After<'a>>,
    /// The `FIELD` block whose arrays come next, while some are left.
    field: Option<FieldBlock<'a>>,
    /// The number arrays of point, cell and field data met so far (`Walk::arrays`).
    arrays: Vec<Array<'a>>,
}

impl<'a> Declared<'a> {
    /// Notes the number array `name` of type `kind` that `header` declares (both words of its
    /// text) in the section open, and gives back its type.
    fn met(
        &mut self,
        header: Header<'a>,
        name: Option<&'a str>,
        kind: Option<&'a str>,
    ) -> Option<&'a str> {
        if let (Some(name), Some(kind)) = (name, kind) {
            self.arrays.push(Array {
                name,
                kind,
                kind_at: header.at + (kind.as_ptr() as usize - header.text.as_ptr() as usize),
                of: self.attributes,
            });
        }
        kind
    }
}

/// An unread array or section just measured, for the line after it.
#[derive(Clone, Copy)]
struct After<'a> {
    header: Header<'a>,
    /// The strings or values it holds.
    count: u64,
}

/// A count of values, or the product that overflowed computing it.
enum Count {
    Values(u64),
    Overflow(String),
}

fn product(count: u64, per: u64) -> Count {
    count.checked_mul(per).map_or_else(
        || Count::Overflow(format!("{count} × {per}")),
        Count::Values,
    )
}

/// What a header line starts.
enum Step<'a> {
    /// A block of values, of the type named (if the header names one). `scalars`: a `SCALARS`
    /// header, which a `LOOKUP_TABLE name` line may follow before the values.
    Data {
        values: Count,
        kind: Option<&'a str>,
        scalars: bool,
    },
    /// A string array: `strings` of them, in a `FIELD` block or a section of its own.
    Strings { strings: Count, within: Within<'a> },
    /// An id section of numbers or variants: `values` of them, laid out as `layout`, one a node
    /// or cell of the section `of` (`POINT_DATA n` or `CELL_DATA n`).
    Ids {
        values: u64,
        layout: Layout,
        of: Header<'a>,
    },
    /// A header with no values of its own (`DATASET`, `POINT_DATA n`, `FIELD name n`, ...).
    NoData,
    /// A line this walk does not know.
    Unknown,
}

/// The first section at fault in a legacy file that vtkio's parser refused, as
/// `line N: what is wrong`; `None` when none is found (the parser's own message is then used).
pub(crate) fn fault(bytes: &[u8]) -> Option<String> {
    walk(bytes)?.fault.map(|fault| fault.message)
}

/// Walks the sections of a legacy file; `None` when its third line is neither `ASCII` nor
/// `BINARY`.
pub(crate) fn walk(bytes: &[u8]) -> Option<Walk<'_>> {
    let mut lines = bytes.split(|&b| b == b'\n');
    // Version 5.x lists cells as OFFSETS and CONNECTIVITY under a CELLS line.
    let v5 = lines.next()?.windows(9).any(|w| w == b"Version 5");
    lines.next()?;
    let kind = lines.next()?.trim_ascii();
    let mut walk = Walk::default();
    let mut declared = Declared::default();
    walk.fault = if kind.eq_ignore_ascii_case(b"ascii") {
        ascii_walk(bytes, v5, &mut walk.unread, &mut declared)
    } else if kind.eq_ignore_ascii_case(b"binary") {
        binary_walk(bytes, v5, &mut walk.unread, &mut declared)
    } else {
        return None;
    };
    walk.arrays = declared.arrays;
    walk.binary = kind.eq_ignore_ascii_case(b"binary");
    Some(walk)
}

/// Reads one header line; `Err` names a `POINT_DATA` or `CELL_DATA` count that is not the
/// file's, an array of such a section after or of a string array whose tuples are not that
/// count (a string array must hold one string a node or cell; a wrong length among the strings
/// before would land the walk on bytes that read as an array header), and an id section VTK's
/// reader would not read.
fn section<'a>(
    header: Header<'a>,
    v5: bool,
    declared: &mut Declared<'a>,
) -> Result<Step<'a>, Fault> {
    let mut words = header.text.split_whitespace();
    let Some(keyword) = words.next() else {
        return Ok(Step::Unknown);
    };
    // A `FIELD` block's arrays follow its header: any other header ends it.
    let field = declared.field.take();
    let after_unread = declared.after_unread.take();
    let count = |word: Option<&str>| word.and_then(|n| n.parse::<u64>().ok());
    let data = |values, kind| Step::Data {
        values,
        kind,
        scalars: false,
    };
    Ok(match keyword.to_ascii_uppercase().as_str() {
        "DATASET" => Step::NoData,
        "FIELD" => {
            if let (Some(_name), Some(arrays), None) =
                (words.next(), count(words.next()), words.next())
            {
                declared.field = Some(FieldBlock {
                    header,
                    arrays,
                    met: 0,
                });
            }
            Step::NoData
        }
        "POINTS" => match count(words.next()) {
            Some(n) => {
                declared.points = Some((n, header));
                let kind = words.next();
                // VTK writes the points' own type, which may be an integer one (a `vtkPoints`
                // of ints); vtkio's parser reads float and double points only, and refused
                // such a file quoting the first values as if they were the fault.
                if let Some(kind) = kind
                    && type_size(kind).is_some()
                    && !["float", "double"]
                        .iter()
                        .any(|k| kind.eq_ignore_ascii_case(k))
                {
                    return Err(Fault::section(format!(
                        "line {}: `{}`: points of type {kind}, which this reader does not read in a \
                         legacy file (write the points as float or double, or the mesh as an XML \
                         .vtu file, whose points may be of any type)",
                        header.line, header.text
                    )));
                }
                data(product(n, 3), kind)
            }
            None => Step::Unknown,
        },
        "CELLS" => match (count(words.next()), count(words.next())) {
            (Some(n), Some(size)) => {
                declared.cells = (n, size);
                if v5 {
                    Step::NoData
                } else {
                    data(Count::Values(size), Some("int"))
                }
            }
            _ => Step::Unknown,
        },
        "OFFSETS" if v5 => data(Count::Values(declared.cells.0), words.next()),
        "CONNECTIVITY" if v5 => data(Count::Values(declared.cells.1), words.next()),
        "CELL_TYPES" => match count(words.next()) {
            Some(n) => {
                declared.cell_types = Some((n, header));
                data(Count::Values(n), Some("int"))
            }
            None => Step::Unknown,
        },
        which @ ("POINT_DATA" | "CELL_DATA") => match count(words.next()) {
            Some(n) => {
                let (what, by) = if which == "POINT_DATA" {
                    ("nodes", declared.points)
                } else {
                    ("cells", declared.cell_types)
                };
                if let Some((expected, by)) = by
                    && expected != n
                {
                    return Err(Fault {
                        unparsed_count: true,
                        ..Fault::section(format!(
                            "line {}: `{}` does not match the {expected} {what} that `{}` (line \
                             {}) declares",
                            header.line, header.text, by.text, by.line
                        ))
                    });
                }
                declared.tuples = n;
                declared.attributes = Some(header);
                Step::NoData
            }
            None => Step::Unknown,
        },
        which @ ("GLOBAL_IDS" | "PEDIGREE_IDS" | "EDGE_FLAGS") => {
            id_section(header, which, declared)?
        }
        "TENSORS6" => tensors6(header, declared)?,
        // Attributes vtkio reads but the reader never needs, measured so that a binary walk
        // goes on past them (to the id sections and string arrays after them, which it must
        // find): as `vtkDataReader` reads them, texture coordinates of `dim` components,
        // 3 × 3 tensors, colour scalars of `n` components (bytes in a binary file, floats in an
        // ASCII one) and a lookup table of `size` RGBA entries (the same).
        "TEXTURE_COORDINATES" => match (words.next(), count(words.next()), words.next()) {
            (Some(_name), Some(dim), kind) => data(product(declared.tuples, dim), kind),
            _ => Step::Unknown,
        },
        "TENSORS" => {
            let _name = words.next();
            data(product(declared.tuples, 9), words.next())
        }
        "COLOR_SCALARS" => match (words.next(), count(words.next())) {
            (Some(_name), Some(n)) => data(product(declared.tuples, n), Some("unsigned_char")),
            _ => Step::Unknown,
        },
        // A lookup table of its own (`LOOKUP_TABLE name size`), not the `LOOKUP_TABLE name` line
        // of a `SCALARS` section, which names no size.
        "LOOKUP_TABLE" => match (words.next(), count(words.next())) {
            (Some(_name), Some(size)) => data(product(size, 4), Some("unsigned_char")),
            _ => Step::Unknown,
        },
        "VECTORS" | "NORMALS" => {
            let kind = declared.met(header, words.next(), words.next());
            data(product(declared.tuples, 3), kind)
        }
        "SCALARS" => {
            let kind = declared.met(header, words.next(), words.next());
            let components = match words.next() {
                None => 1,
                Some(n) => match n.parse::<u64>() {
                    Ok(n) => n,
                    Err(_) => return Ok(Step::Unknown),
                },
            };
            Step::Data {
                values: product(declared.tuples, components),
                kind,
                scalars: true,
            }
        }
        // A FIELD array: `name components tuples type`.
        _ => match (count(words.next()), count(words.next()), words.next()) {
            (Some(components), Some(tuples), Some(kind)) if words.next().is_none() => {
                let values = product(components, tuples);
                match field {
                    Some(mut block) if block.met < block.arrays => {
                        block.met += 1;
                        declared.field = Some(block);
                        // As VTK's reader names them (case and all).
                        let strings = matches!(kind, "string" | "utf8_string");
                        if let Some(attributes) = declared.attributes
                            && tuples != declared.tuples
                        {
                            let n = declared.tuples;
                            if let Some(before) = after_unread {
                                return Err(Fault::unread(format!(
                                    "line {}: {} ends where `{}` (line {}) starts, an array of \
                                     {tuples} tuples where `{}` (line {}) declares {n} (a wrong \
                                     length or count of its strings?)",
                                    before.header.line,
                                    called(before.header),
                                    header.text,
                                    header.line,
                                    attributes.text,
                                    attributes.line
                                )));
                            }
                            if strings {
                                return Err(Fault::unread(format!(
                                    "line {}: the string array `{}` has {tuples} tuples, but \
                                     `{}` (line {}) declares {n}",
                                    header.line, header.text, attributes.text, attributes.line
                                )));
                            }
                        }
                        if strings {
                            Step::Strings {
                                strings: values,
                                within: Within::Field {
                                    header: block.header,
                                    arrays: block.arrays,
                                },
                            }
                        } else {
                            data(values, declared.met(header, Some(keyword), Some(kind)))
                        }
                    }
                    _ => data(values, Some(kind)),
                }
            }
            _ => Step::Unknown,
        },
    })
}

/// How an id section's values are laid out.
#[derive(Clone, Copy)]
enum Layout {
    /// Numbers: in a binary file, big-endian, of this many bytes each.
    Numbers(u64),
    /// `bit`: in a binary file, packed 8 a byte (the last byte padded).
    Bits,
    /// `variant`: a line `type value` each, as text in either kind of file.
    Variant,
}

/// Reads the header of an id section, `which name type`, of the point or cell data.
///
/// VTK's reader reads `GLOBAL_IDS` and `PEDIGREE_IDS` in point and cell data, and `EDGE_FLAGS` in
/// point data only; one value a node or cell, of the type the header names (lowercased:
/// `vtkDataReader::ReadArray`). A string type is measured as a string array.
fn id_section<'a>(
    header: Header<'a>,
    which: &str,
    declared: &Declared<'a>,
) -> Result<Step<'a>, Fault> {
    let refuse = |what: String| Err(Fault::unread(format!("line {}: {what}", header.line)));
    let mut words = header.text.split_whitespace().skip(1);
    let (Some(_name), Some(kind), None) = (words.next(), words.next(), words.next()) else {
        return refuse(format!(
            "{} is not `{which} name type`",
            crate::excerpt(header.text.as_bytes(), 60)
        ));
    };
    let Some(of) = declared.attributes else {
        return refuse(format!(
            "the `{}` section comes before any `POINT_DATA n` or `CELL_DATA n` line (it holds \
             one value a node or cell)",
            header.text
        ));
    };
    let cell_data = of
        .text
        .get(..9)
        .is_some_and(|start| start.eq_ignore_ascii_case("CELL_DATA"));
    if which == "EDGE_FLAGS" && cell_data {
        return refuse(format!(
            "the `{}` section is cell data (of `{}`, line {}): VTK reads edge flags of point \
             data only",
            header.text, of.text, of.line
        ));
    }
    let values = declared.tuples;
    Ok(match kind.to_ascii_lowercase().as_str() {
        "string" | "utf8_string" => Step::Strings {
            strings: Count::Values(values),
            within: Within::Attribute(header),
        },
        "variant" => Step::Ids {
            values,
            layout: Layout::Variant,
            of,
        },
        "bit" => Step::Ids {
            values,
            layout: Layout::Bits,
            of,
        },
        number => match type_size(number) {
            Some(size) => Step::Ids {
                values,
                layout: Layout::Numbers(size),
                of,
            },
            None => {
                return refuse(format!(
                    "the `{}` section is of type {}, which VTK's reader does not read",
                    header.text,
                    crate::excerpt(kind.as_bytes(), 30)
                ));
            }
        },
    })
}

/// Reads the header of a symmetric tensor section, `TENSORS6 name type`, of the point or cell
/// data: six values a node or cell, of a number type. vtkio's parser does not know the keyword
/// (VTK's legacy writer uses it for every tensor array of 6 components, a solver's strain or
/// stress), and refused the whole file. Such an array is never the displacement, so it is measured
/// and blanked out as an id section of six values a node or cell is.
fn tensors6<'a>(header: Header<'a>, declared: &Declared<'a>) -> Result<Step<'a>, Fault> {
    let mut words = header.text.split_whitespace().skip(1);
    let (Some(_name), Some(kind), None, Some(of)) = (
        words.next(),
        words.next(),
        words.next(),
        declared.attributes,
    ) else {
        return Ok(Step::Unknown);
    };
    let Some(size) = type_size(kind) else {
        return Ok(Step::Unknown);
    };
    let Some(values) = declared.tuples.checked_mul(6) else {
        return Err(Fault::unread(overflow(
            header,
            &format!("{} × 6 values", declared.tuples),
        )));
    };
    Ok(Step::Ids {
        values,
        layout: Layout::Numbers(size),
        of,
    })
}

/// Whether a header line starts an id section (or a `TENSORS6` section, measured as one).
fn id_header(text: &str) -> bool {
    text.split_whitespace().next().is_some_and(|keyword| {
        ["GLOBAL_IDS", "PEDIGREE_IDS", "EDGE_FLAGS", "TENSORS6"]
            .iter()
            .any(|k| keyword.eq_ignore_ascii_case(k))
    })
}

/// How a message names an unread array: `the string array `name 1 10 string`` or `the
/// `GLOBAL_IDS name vtkIdType` section`.
fn called(header: Header) -> String {
    if id_header(header.text) {
        format!("the `{}` section", header.text)
    } else {
        format!("the string array `{}`", header.text)
    }
}

/// What an unread array holds: `strings` or `values`.
fn unit(header: Header) -> &'static str {
    let kind = header.text.split_whitespace().last().unwrap_or_default();
    if ["string", "utf8_string"]
        .iter()
        .any(|k| kind.eq_ignore_ascii_case(k))
    {
        "strings"
    } else {
        "values"
    }
}

fn overflow(header: Header, what: &str) -> String {
    format!(
        "line {}: the `{}` section declares an impossible count ({what} do not fit in 64 bits)",
        header.line, header.text
    )
}

/// A line that is empty but for its line end: where a `METADATA` block ends, as vtkio's parser
/// ends it.
fn empty_line(raw: &[u8]) -> bool {
    matches!(raw, b"" | b"\n" | b"\r" | b"\r\n")
}

/// The keywords that start the header lines of legacy files (data sets of every kind).
const KEYWORDS: [&str; 33] = [
    "DATASET",
    "FIELD",
    "POINTS",
    "CELLS",
    "OFFSETS",
    "CONNECTIVITY",
    "CELL_TYPES",
    "POINT_DATA",
    "CELL_DATA",
    "SCALARS",
    "COLOR_SCALARS",
    "LOOKUP_TABLE",
    "VECTORS",
    "NORMALS",
    "TEXTURE_COORDINATES",
    "TENSORS",
    "TENSORS6",
    "GLOBAL_IDS",
    "PEDIGREE_IDS",
    "EDGE_FLAGS",
    "METADATA",
    "NULL_ARRAY",
    "DIMENSIONS",
    "ORIGIN",
    "SPACING",
    "ASPECT_RATIO",
    "X_COORDINATES",
    "Y_COORDINATES",
    "Z_COORDINATES",
    "VERTICES",
    "LINES",
    "POLYGONS",
    "TRIANGLE_STRIPS",
];

/// A line that should be a header, for a message: quoted when it is text, else its first bytes in
/// hex (binary values, which quoted would read as a row of escapes).
fn shown(line: &[u8]) -> String {
    match std::str::from_utf8(line) {
        Ok(text) if !text.chars().any(|c| c.is_control() && !c.is_whitespace()) => {
            crate::excerpt(text.trim_ascii().as_bytes(), 40)
        }
        _ => {
            let hex: Vec<String> = line.iter().take(8).map(|b| format!("{b:02x}")).collect();
            let more = if line.len() > 8 { " …" } else { "" };
            format!("binary bytes ({}{more})", hex.join(" "))
        }
    }
}

/// Whether a line reads as a header: a keyword first, or a `FIELD` array's `name n n type`.
fn header_shaped(text: &str) -> bool {
    let words: Vec<&str> = text.split_whitespace().take(5).collect();
    let is_count = |word: &str| word.parse::<u64>().is_ok();
    match words.as_slice() {
        [] => false,
        [_, components, tuples, _] if is_count(components) && is_count(tuples) => true,
        [keyword, ..] => KEYWORDS.iter().any(|k| keyword.eq_ignore_ascii_case(k)),
    }
}

/// Whether a line where an ASCII string array's next string should be is a header instead: a
/// header of 2 to 4 words. VTK's writer percent-encodes every byte below 33 in a string, so no
/// string it wrote has two words.
fn header_among_strings(raw: &[u8]) -> bool {
    std::str::from_utf8(raw).is_ok_and(|text| {
        (2..=4).contains(&text.split_whitespace().take(5).count()) && header_shaped(text)
    })
}

/// Whether a line of a `METADATA` block is a section header instead, the block's empty line
/// missing: a keyword and 1 to 3 more words. (The block's own lines are `COMPONENT_NAMES`,
/// `INFORMATION n`, `NAME key LOCATION where`, `DATA ...` and encoded names of one word.)
fn header_in_metadata(raw: &[u8]) -> bool {
    std::str::from_utf8(raw).is_ok_and(|text| {
        let words = text.split_whitespace().take(5).count();
        (2..=4).contains(&words)
            && text
                .split_whitespace()
                .next()
                .is_some_and(|keyword| KEYWORDS.iter().any(|k| keyword.eq_ignore_ascii_case(k)))
    })
}

/// A `METADATA` block after a string array or an id section that runs into a header or into
/// bytes that are not text: its empty line is missing, and blanking it would blank what follows.
fn unended(after: After, line: usize, text: &[u8]) -> Fault {
    Fault::unread(format!(
        "line {}: the METADATA block after {} (line {}) runs into line {line}, {}, without the \
         empty line that ends it",
        after.header.line,
        called(after.header),
        after.header.line,
        crate::excerpt(text.trim_ascii(), 40)
    ))
}

/// A line after a string array's strings or an id section's values that is no header: a string
/// or value beyond its count.
fn beyond(after: After, line: usize, text: &[u8]) -> Fault {
    let (header, count) = (after.header, after.count);
    Fault::unread(format!(
        "line {}: {} holds more than its {count} {}: line {line}, {}, follows them where a \
         header should (a wrong count?)",
        header.line,
        called(header),
        unit(header),
        crate::excerpt(text.trim_ascii(), 40)
    ))
}

/// Whether the line after an unread array or section, `text`, is where its values end: a header.
/// After an id section no number follows (its values are one a node or cell): a `FIELD` array
/// named as a number is read after string arrays only.
fn ends_values(after: After, text: &str) -> bool {
    header_shaped(text)
        && !(id_header(after.header.text)
            && text
                .split_whitespace()
                .next()
                .is_some_and(|first| first.parse::<f64>().is_ok()))
}

/// Extends the last unread array or section over the `METADATA` block at `block`, when nothing
/// but whitespace lies between them: the block belongs to it.
fn metadata_of_unread(bytes: &[u8], unread: &mut [Unread], block: Range<usize>) {
    if let Some(last) = unread.last_mut()
        && bytes
            .get(last.span.end..block.start)
            .is_some_and(|between| between.iter().all(u8::is_ascii_whitespace))
    {
        last.span.end = block.end;
    }
}

/// How values written as words end (numbers, variants: VTK's reader reads them with `>>`, over
/// any lines), or what is wrong with them.
enum Words {
    /// All read: the byte after the line end of the line holding the last.
    End(usize),
    /// The file ends after `found` of them.
    Cut { found: u64 },
    /// The line at this byte holds no more of them after `found`: a header, or a corrupt value.
    Stopped { found: u64, at: usize },
    /// The line at this byte, which holds the last, holds more after it.
    More { at: usize },
}

/// Reads `count` words from the line at byte `from` on, each checked by `valid` (its index and
/// its bytes).
fn words(bytes: &[u8], from: usize, count: u64, valid: impl Fn(u64, &[u8]) -> bool) -> Words {
    let mut found = 0;
    let mut at = from;
    while found < count {
        if at >= bytes.len() {
            return Words::Cut { found };
        }
        let end = bytes[at..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| at + i + 1);
        for word in bytes[at..end]
            .split(u8::is_ascii_whitespace)
            .filter(|w| !w.is_empty())
        {
            if found == count {
                return Words::More { at };
            }
            if !valid(found, word) {
                return Words::Stopped { found, at };
            }
            found += 1;
        }
        at = end;
    }
    Words::End(at)
}

/// The 1-based line of byte `at`.
fn line_at(bytes: &[u8], at: usize) -> usize {
    1 + bytes[..at].iter().filter(|&&b| b == b'\n').count()
}

/// The line at byte `at`, for a message.
fn line_text(bytes: &[u8], at: usize) -> &[u8] {
    let rest = &bytes[at.min(bytes.len())..];
    let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
    &rest[..end]
}

/// Measures the values of an id section of numbers, bits (in an ASCII file) or variants as
/// words from byte `from` on: where they end, or the fault.
fn id_words(
    bytes: &[u8],
    header: Header,
    from: usize,
    values: u64,
    layout: Layout,
    of: Header,
) -> Result<usize, Fault> {
    let number = |word: &[u8]| std::str::from_utf8(word).is_ok_and(|w| w.parse::<f64>().is_ok());
    // A variant is two words, its VTK type (a number) and its value (percent-encoded).
    let (count, per) = match layout {
        Layout::Variant => match values.checked_mul(2) {
            Some(words) => (words, 2),
            None => {
                return Err(Fault::unread(overflow(
                    header,
                    &format!("{values} × 2 words"),
                )));
            }
        },
        Layout::Numbers(_) | Layout::Bits => (values, 1),
    };
    let valid = |index: u64, word: &[u8]| index % per != 0 || number(word);
    let declared = format!(
        "the {values} values that `{}` (line {}) declares",
        of.text, of.line
    );
    let section = format!("line {}: the `{}` section", header.line, header.text);
    match words(bytes, from, count, valid) {
        Words::End(end) => Ok(end),
        Words::Cut { found } => Err(Fault::unread(format!(
            "{section} holds {} of {declared} (the file is cut, or values are missing)",
            found / per
        ))),
        Words::Stopped { found, at } => Err(Fault::unread(format!(
            "{section} holds {} of {declared}: line {}, {}, is no value of it (values are \
             missing, or one is corrupt)",
            found / per,
            line_at(bytes, at),
            crate::excerpt(line_text(bytes, at).trim_ascii(), 40)
        ))),
        Words::More { at } => Err(Fault::unread(format!(
            "{section} holds more than {declared}: line {}, {}, holds the last and more",
            line_at(bytes, at),
            crate::excerpt(line_text(bytes, at).trim_ascii(), 40)
        ))),
    }
}

/// An ASCII file: the values of each section are counted against its header; the strings of a
/// string array are the lines after its header, one each; the values of an id section are
/// measured as words.
fn ascii_walk<'a>(
    bytes: &'a [u8],
    v5: bool,
    unread: &mut Vec<Unread<'a>>,
    declared: &mut Declared<'a>,
) -> Option<Fault> {
    let number = |t: &str| t.parse::<f64>().is_ok() || t.eq_ignore_ascii_case("nan");
    // The open section: its header, the values it declares, those found, and where it ends.
    struct Open<'a> {
        header: Header<'a>,
        expected: u64,
        found: u64,
        /// Bytes of the file after its header line.
        room: usize,
        scalars: bool,
    }
    let short = |open: Open| {
        (open.found < open.expected).then(|| {
            // Each value takes a byte and a separator.
            let hint = if open.expected > (open.room as u64).div_ceil(2) {
                format!(
                    "more than the {} bytes after it can hold: a wrong count, or the file is cut",
                    open.room
                )
            } else {
                "the file is cut, or values are missing".to_owned()
            };
            Fault::section(format!(
                "line {}: the `{}` section holds {} of its {} values ({hint})",
                open.header.line, open.header.text, open.found, open.expected
            ))
        })
    };
    let mut current: Option<Open> = None;
    // Each line with its 1-based number and the byte it starts at.
    let mut lines = bytes
        .split_inclusive(|&b| b == b'\n')
        .scan(0, |offset, raw| {
            let at = *offset;
            *offset += raw.len();
            Some((at, raw))
        })
        .zip(1..)
        .map(|((at, raw), line)| (line, at, raw))
        .peekable();
    // The first three lines are the version, the title (anything) and `ASCII`.
    for _ in 0..3 {
        lines.next();
    }
    while let Some((number_of_line, at, raw)) = lines.next() {
        let after_unread = declared.after_unread;
        // A line that is not text: what follows cannot be told apart.
        let Ok(untrimmed) = std::str::from_utf8(raw) else {
            return after_unread.map(|after| beyond(after, number_of_line, raw));
        };
        let line = untrimmed.trim();
        let Some(first) = line.split_whitespace().next() else {
            continue;
        };
        if let Some(after) = after_unread
            && !ends_values(after, line)
        {
            return Some(beyond(after, number_of_line, line.as_bytes()));
        }
        if number(first) {
            if let Some(open) = &mut current {
                open.found += line.split_whitespace().filter(|t| number(t)).count() as u64;
            }
            continue;
        }
        if first.eq_ignore_ascii_case("LOOKUP_TABLE")
            && current.as_ref().is_some_and(|o| o.scalars && o.found == 0)
        {
            continue;
        }
        if let Some(fault) = current.take().and_then(short) {
            return Some(fault);
        }
        if line.eq_ignore_ascii_case("METADATA") {
            let mut end = at + raw.len();
            for (metadata_line, line_at, raw) in lines.by_ref() {
                if let Some(after) = after_unread
                    && (std::str::from_utf8(raw).is_err() || header_in_metadata(raw))
                {
                    return Some(unended(after, metadata_line, raw));
                }
                end = line_at + raw.len();
                if empty_line(raw) {
                    break;
                }
            }
            metadata_of_unread(bytes, unread, at..end);
            continue;
        }
        let header = Header {
            line: number_of_line,
            at: at + (untrimmed.len() - untrimmed.trim_start().len()),
            text: line,
        };
        current = match section(header, v5, declared) {
            Err(fault) => return Some(fault),
            Ok(Step::Data {
                values: Count::Overflow(what),
                ..
            }) => return Some(Fault::section(overflow(header, &format!("{what} values")))),
            Ok(Step::Data {
                values: Count::Values(expected),
                scalars,
                ..
            }) => Some(Open {
                header,
                expected,
                found: 0,
                room: bytes.len() - (at + raw.len()),
                scalars,
            }),
            Ok(Step::Strings {
                strings: count,
                within,
            }) => {
                let count = match count {
                    Count::Values(n) => n,
                    Count::Overflow(what) => {
                        return Some(Fault::unread(overflow(header, &format!("{what} strings"))));
                    }
                };
                let mut end = at + raw.len();
                // Ends with the lines: a count past them is a cut file.
                for met in 0..count {
                    let held = |more: &str| {
                        Fault::unread(format!(
                            "line {}: {} holds {met} of its {count} strings{more}",
                            header.line,
                            called(header)
                        ))
                    };
                    let Some((string_line, string_at, string)) = lines.next() else {
                        return Some(held(" (the file is cut, or strings are missing)"));
                    };
                    if header_among_strings(string) {
                        return Some(held(&format!(
                            ": line {string_line} is a section header, {} (VTK writes one \
                             string a line, its spaces encoded): a wrong count, or strings are \
                             missing",
                            crate::excerpt(string.trim_ascii(), 40)
                        )));
                    }
                    end = string_at + string.len();
                }
                unread.push(Unread {
                    within,
                    span: header.at..end,
                });
                declared.after_unread = Some(After { header, count });
                None
            }
            Ok(Step::Ids { values, layout, of }) => {
                let end = match id_words(bytes, header, at + raw.len(), values, layout, of) {
                    Ok(end) => end,
                    Err(fault) => return Some(fault),
                };
                while lines.next_if(|&(_, line_at, _)| line_at < end).is_some() {}
                unread.push(Unread {
                    within: Within::Attribute(header),
                    span: header.at..end,
                });
                declared.after_unread = Some(After {
                    header,
                    count: values,
                });
                None
            }
            Ok(_) => None,
        };
    }
    current.and_then(short)
}

/// Bytes per value of a legacy type name; `None` for `bit` (packed) and names not known.
fn type_size(kind: &str) -> Option<u64> {
    Some(match kind.to_ascii_lowercase().as_str() {
        "char" | "signed_char" | "unsigned_char" => 1,
        "short" | "unsigned_short" => 2,
        "int" | "unsigned_int" | "float" | "vtkidtype" => 4,
        "long" | "unsigned_long" | "double" | "vtktypeint64" | "vtktypeuint64" => 8,
        _ => return None,
    })
}

/// A binary file: each header's values are measured in bytes and skipped, and a section whose
/// bytes run past the end of the file is named; a string array's strings are skipped by their
/// lengths, an id section's variants as words.
fn binary_walk<'a>(
    bytes: &'a [u8],
    v5: bool,
    unread: &mut Vec<Unread<'a>>,
    declared: &mut Declared<'a>,
) -> Option<Fault> {
    let len = bytes.len();
    let line_end = |from: usize| {
        bytes[from..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(len, |i| from + i)
    };
    let skip_blank = |from: usize| {
        from + bytes[from..]
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(len - from)
    };
    // Line numbers count every line end before, those inside binary data included.
    let (mut counted, mut newlines) = (0, 0);
    let mut line_of = |at: usize| {
        newlines += bytes[counted..at].iter().filter(|&&b| b == b'\n').count();
        counted = at;
        newlines + 1
    };
    // After the version, the title and `BINARY`.
    let mut at = 0;
    for _ in 0..3 {
        at = (line_end(at) + 1).min(len);
    }
    // The block of values just measured, for the line after it: its header, its values, their
    // bytes each, and where they end.
    let mut after_values: Option<(Header, u64, u64, usize)> = None;
    loop {
        let after_unread = declared.after_unread;
        at = skip_blank(at);
        if at >= len {
            return None;
        }
        let end = line_end(at);
        let line = line_of(at);
        // A block of values must end where a header (or the file) starts: values of another
        // count or type end elsewhere, inside the next section's header or values. vtkio's
        // parser then fails on the bytes it lands on, with a message that quotes them.
        if let Some((header, values, size, ends)) = after_values.take()
            && !std::str::from_utf8(&bytes[at..end]).is_ok_and(header_shaped)
        {
            return Some(Fault::section(format!(
                "line {}: the `{}` section's {values} values of {size} bytes end at byte \
                 {ends}, and no section header follows them but {} (a count that does not \
                 match the values, or values of another type?)",
                header.line,
                header.text,
                shown(&bytes[at..end])
            )));
        }
        let text = match std::str::from_utf8(&bytes[at..end]) {
            Ok(text) if after_unread.is_none_or(|after| ends_values(after, text)) => text.trim(),
            // Not text: what follows cannot be told apart.
            _ => return after_unread.map(|after| beyond(after, line, &bytes[at..end])),
        };
        let header = Header { line, at, text };
        let mut data = (end + 1).min(len);
        if header.text.eq_ignore_ascii_case("METADATA") {
            // Lines of text, up to an empty one.
            while data < len {
                let raw = &bytes[data..line_end(data)];
                if let Some(after) = after_unread
                    && (std::str::from_utf8(raw).is_err() || header_in_metadata(raw))
                {
                    return Some(unended(after, line_of(data), raw));
                }
                data = (data + raw.len() + 1).min(len);
                if empty_line(raw) {
                    break;
                }
            }
            metadata_of_unread(bytes, unread, at..data);
            at = data;
            continue;
        }
        match section(header, v5, declared) {
            Err(fault) => return Some(fault),
            Ok(Step::Unknown) => return None,
            Ok(Step::NoData) => {}
            Ok(Step::Strings {
                strings: count,
                within,
            }) => {
                let count = match count {
                    Count::Values(n) => n,
                    Count::Overflow(what) => {
                        return Some(Fault::unread(overflow(header, &format!("{what} strings"))));
                    }
                };
                // Each string takes a byte at least: the loop ends with the file.
                for met in 0..count {
                    let fault = |what: String| {
                        Some(Fault::unread(format!(
                            "line {}: {}: string {} of {count} {what} (a wrong count or length, \
                             or the file is cut)",
                            header.line,
                            called(header),
                            met + 1
                        )))
                    };
                    let Some(&first) = bytes.get(data) else {
                        return fault("is past the end of the file".to_owned());
                    };
                    // The first two bits give the length's width; the rest of it, the length.
                    let width = match first >> 6 {
                        3 => 1,
                        2 => 2,
                        1 => 4,
                        _ => 8,
                    };
                    let Some(head) = bytes.get(data..data + width) else {
                        return fault(format!(
                            "has a {width}-byte length, but the file ends inside it"
                        ));
                    };
                    let mut length = head.iter().fold(0u64, |n, &b| (n << 8) | u64::from(b));
                    if width < 8 {
                        length &= (1 << (8 * width - 2)) - 1;
                    }
                    data += width;
                    let room = (len - data) as u64;
                    if length > room {
                        return fault(format!(
                            "is {length} bytes long, but only {room} bytes follow its length"
                        ));
                    }
                    data += length as usize;
                }
                // VTK's writer ends the strings with a line end: a wrong length that ends them
                // elsewhere would blank the start of the next header (a renamed array).
                if bytes.get(data).is_some_and(|&b| b != b'\n') {
                    return Some(Fault::unread(format!(
                        "line {}: {}: its {count} strings end at byte {data}, where VTK writes a \
                         line end, not {} (a wrong count or length?)",
                        header.line,
                        called(header),
                        crate::excerpt(&bytes[data..(data + 12).min(len)], 12)
                    )));
                }
                unread.push(Unread {
                    within,
                    span: at..data,
                });
                declared.after_unread = Some(After { header, count });
            }
            Ok(Step::Ids { values, layout, of }) => {
                let declared_by = || {
                    format!(
                        "the {values} values that `{}` (line {}) declares",
                        of.text, of.line
                    )
                };
                let size = match layout {
                    Layout::Variant => None,
                    Layout::Numbers(size) => Some(values.checked_mul(size)),
                    Layout::Bits => Some(Some(values.div_ceil(8))),
                };
                match size {
                    // Variants are text, in binary files too.
                    None => match id_words(bytes, header, data, values, layout, of) {
                        Ok(end) => data = end,
                        Err(fault) => return Some(fault),
                    },
                    Some(None) => {
                        return Some(Fault::unread(overflow(
                            header,
                            &format!("{values} values × their bytes"),
                        )));
                    }
                    Some(Some(need)) => {
                        let room = (len - data) as u64;
                        if need > room {
                            return Some(Fault::unread(format!(
                                "line {}: the `{}` section needs {need} bytes for {}, but only \
                                 {room} bytes follow its header (the file is cut?)",
                                header.line,
                                header.text,
                                declared_by()
                            )));
                        }
                        data += need as usize;
                        // VTK's writer ends the values with a line end: values of another count
                        // or size end them elsewhere.
                        if bytes.get(data).is_some_and(|&b| b != b'\n') {
                            return Some(Fault::unread(format!(
                                "line {}: the `{}` section: {} end at byte {data}, where VTK \
                                 writes a line end, not {} (more values, or values of another \
                                 type?)",
                                header.line,
                                header.text,
                                declared_by(),
                                crate::excerpt(&bytes[data..(data + 12).min(len)], 12)
                            )));
                        }
                    }
                }
                unread.push(Unread {
                    within: Within::Attribute(header),
                    span: at..data,
                });
                declared.after_unread = Some(After {
                    header,
                    count: values,
                });
            }
            Ok(Step::Data {
                values,
                kind,
                scalars,
            }) => {
                let values = match values {
                    Count::Values(n) => n,
                    Count::Overflow(what) => {
                        return Some(Fault::section(overflow(header, &format!("{what} values"))));
                    }
                };
                if scalars {
                    let next = skip_blank(data);
                    if bytes.len() >= next + 12
                        && bytes[next..next + 12].eq_ignore_ascii_case(b"LOOKUP_TABLE")
                    {
                        data = (line_end(next) + 1).min(len);
                    }
                }
                let size = type_size(kind?)?;
                let Some(need) = values.checked_mul(size) else {
                    return Some(Fault::section(overflow(
                        header,
                        &format!("{values} values × {size} bytes"),
                    )));
                };
                let room = (len - data) as u64;
                if need > room {
                    return Some(Fault::section(format!(
                        "line {}: the `{}` section declares {values} values of {size} bytes, \
                         but only {room} bytes follow its header (a wrong count, or the file is \
                         cut)",
                        header.line, header.text
                    )));
                }
                data += need as usize;
                after_values = Some((header, values, size, data));
            }
        }
        at = data;
    }
}
