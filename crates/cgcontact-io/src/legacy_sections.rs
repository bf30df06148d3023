//! Which section of a legacy VTK file is at fault, for when vtkio's parser gives up on it.
//!
//! vtkio's legacy parser backtracks to the start of a section it cannot finish (often to line 1,
//! `# vtk DataFile Version 4.2`) and its errors carry no position. So when it fails, the sections
//! are walked here against their headers, and the first one at fault is named with its line:
//! - a count that overflows 64 bits (`POINTS 12297829382473034438 double`: 3 × n values);
//! - a `POINT_DATA n` or `CELL_DATA n` that is not the file's node or cell count;
//! - in an ASCII file, a section holding fewer values than its header declares (counted);
//! - in a binary file, a section whose bytes run past the end of the file (`POINTS 4000000000
//!   double` in a file of 4 KB).
//!
//! The same walk finds the string arrays of `FIELD` blocks (`name components tuples string`),
//! which vtkio's parser cannot read, for `legacy_strings` to blank out before it parses; a string
//! array that does not hold what it declares is a fault (cut, a length past the end of the file,
//! an ASCII count above or below its strings, binary strings that do not end at VTK's line end,
//! other tuples than its section's nodes or cells, an array after it with other tuples: where a
//! wrong length lands the walk). The walk measures
//! them as VTK's reader reads them (`vtkDataReader::ReadArray`): in an ASCII file one string a
//! line, percent-encoded by the writer so that it holds no whitespace (an empty string is an empty
//! line); in a binary file each string's bytes after a big-endian length whose first two bits
//! give its width (`11`: 6 bits in 1 byte, `10`: 14 bits in 2, `01`: 30 bits in 4, `00`: 64 bits
//! in 8). A `METADATA` block (text, up to an empty line, in either kind of file) is skipped, and
//! belongs to the string array it follows.

use std::ops::Range;

/// A section's header line (trimmed), its 1-based number and the byte its text starts at.
#[derive(Clone, Copy)]
pub(crate) struct Header<'a> {
    pub(crate) line: usize,
    pub(crate) at: usize,
    pub(crate) text: &'a str,
}

/// A string array of a `FIELD` block, as a walk measured it.
pub(crate) struct StringArray<'a> {
    /// The header line of its `FIELD` block: `FIELD name n`, exactly these words.
    pub(crate) field: Header<'a>,
    /// That block's `n`, the arrays it declares.
    pub(crate) field_arrays: u64,
    /// Its bytes: from its header line to the end of its strings, or of the `METADATA` block
    /// after them.
    pub(crate) span: Range<usize>,
}

/// The first section at fault: `line N: what is wrong`, and whether it is a string array.
pub(crate) struct Fault {
    pub(crate) message: String,
    pub(crate) in_strings: bool,
}

impl Fault {
    fn section(message: String) -> Self {
        Self {
            message,
            in_strings: false,
        }
    }

    fn strings(message: String) -> Self {
        Self {
            message,
            in_strings: true,
        }
    }
}

/// What a walk of a legacy file's sections found: the string arrays of its `FIELD` blocks up to
/// the first fault, or to the first line the walk does not know in a binary file (after which it
/// cannot tell data from headers).
#[derive(Default)]
pub(crate) struct Walk<'a> {
    pub(crate) strings: Vec<StringArray<'a>>,
    pub(crate) fault: Option<Fault>,
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
    /// The string array just measured, and its count: a header must follow it (the walks set
    /// it; the next header read clears it).
    after_strings: Option<(Header<'a>, u64)>,
    /// The `FIELD` block whose arrays come next, while some are left.
    field: Option<FieldBlock<'a>>,
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
    /// A string array of a `FIELD` block: `strings` of them, in its block `field`.
    Strings {
        strings: Count,
        field: FieldBlock<'a>,
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
    walk.fault = if kind.eq_ignore_ascii_case(b"ascii") {
        ascii_walk(bytes, v5, &mut walk.strings)
    } else if kind.eq_ignore_ascii_case(b"binary") {
        binary_walk(bytes, v5, &mut walk.strings)
    } else {
        return None;
    };
    Some(walk)
}

/// Reads one header line; `Err` names a `POINT_DATA` or `CELL_DATA` count that is not the
/// file's, and an array of such a section after or of a string array whose tuples are not that
/// count (a string array must hold one string a node or cell; a wrong length among the strings
/// before would land the walk on bytes that read as an array header).
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
    let after_strings = declared.after_strings.take();
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
                data(product(n, 3), words.next())
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
                    return Err(Fault::section(format!(
                        "line {}: `{}` does not match the {expected} {what} that `{}` (line {}) \
                         declares",
                        header.line, header.text, by.text, by.line
                    )));
                }
                declared.tuples = n;
                declared.attributes = Some(header);
                Step::NoData
            }
            None => Step::Unknown,
        },
        "VECTORS" | "NORMALS" => data(product(declared.tuples, 3), words.nth(1)),
        "SCALARS" => {
            let kind = words.nth(1);
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
                            if let Some((before, _)) = after_strings {
                                return Err(Fault::strings(format!(
                                    "line {}: the string array `{}` ends where `{}` (line {}) \
                                     starts, an array of {tuples} tuples where `{}` (line {}) \
                                     declares {n} (a wrong length or count of its strings?)",
                                    before.line,
                                    before.text,
                                    header.text,
                                    header.line,
                                    attributes.text,
                                    attributes.line
                                )));
                            }
                            if strings {
                                return Err(Fault::strings(format!(
                                    "line {}: the string array `{}` has {tuples} tuples, but \
                                     `{}` (line {}) declares {n}",
                                    header.line, header.text, attributes.text, attributes.line
                                )));
                            }
                        }
                        if strings {
                            Step::Strings {
                                strings: values,
                                field: block,
                            }
                        } else {
                            data(values, Some(kind))
                        }
                    }
                    _ => data(values, Some(kind)),
                }
            }
            _ => Step::Unknown,
        },
    })
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
const KEYWORDS: [&str; 32] = [
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

/// A `METADATA` block after a string array that runs into a header or into bytes that are not
/// text: its empty line is missing, and blanking it would blank what follows.
fn unended(strings: (Header, u64), line: usize, text: &[u8]) -> Fault {
    let (header, _) = strings;
    Fault::strings(format!(
        "line {}: the METADATA block after the string array `{}` (line {}) runs into line \
         {line}, {}, without the empty line that ends it",
        header.line,
        header.text,
        header.line,
        crate::excerpt(text.trim_ascii(), 40)
    ))
}

/// A line after a string array's strings that is no header: a string beyond its count.
fn beyond(strings: (Header, u64), line: usize, text: &[u8]) -> Fault {
    let (header, count) = strings;
    Fault::strings(format!(
        "line {}: the string array `{}` holds more than its {count} strings: line {line}, {}, \
         follows them where a header should (a wrong count?)",
        header.line,
        header.text,
        crate::excerpt(text.trim_ascii(), 40)
    ))
}

/// Extends the last string array over the `METADATA` block at `block`, when nothing but
/// whitespace lies between them: the block belongs to that array.
fn metadata_of_strings(bytes: &[u8], strings: &mut [StringArray], block: Range<usize>) {
    if let Some(last) = strings.last_mut()
        && bytes
            .get(last.span.end..block.start)
            .is_some_and(|between| between.iter().all(u8::is_ascii_whitespace))
    {
        last.span.end = block.end;
    }
}

/// An ASCII file: the values of each section are counted against its header; the strings of a
/// string array are the lines after its header, one each.
fn ascii_walk<'a>(bytes: &'a [u8], v5: bool, strings: &mut Vec<StringArray<'a>>) -> Option<Fault> {
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
    let mut declared = Declared::default();
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
        .map(|((at, raw), line)| (line, at, raw));
    // The first three lines are the version, the title (anything) and `ASCII`.
    for _ in 0..3 {
        lines.next();
    }
    while let Some((number_of_line, at, raw)) = lines.next() {
        let after_strings = declared.after_strings;
        // A line that is not text: what follows cannot be told apart.
        let Ok(untrimmed) = std::str::from_utf8(raw) else {
            return after_strings.map(|strings| beyond(strings, number_of_line, raw));
        };
        let line = untrimmed.trim();
        let Some(first) = line.split_whitespace().next() else {
            continue;
        };
        if let Some(strings) = after_strings
            && !header_shaped(line)
        {
            return Some(beyond(strings, number_of_line, line.as_bytes()));
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
                if let Some(strings) = after_strings
                    && (std::str::from_utf8(raw).is_err() || header_in_metadata(raw))
                {
                    return Some(unended(strings, metadata_line, raw));
                }
                end = line_at + raw.len();
                if empty_line(raw) {
                    break;
                }
            }
            metadata_of_strings(bytes, strings, at..end);
            continue;
        }
        let header = Header {
            line: number_of_line,
            at: at + (untrimmed.len() - untrimmed.trim_start().len()),
            text: line,
        };
        current = match section(header, v5, &mut declared) {
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
                field,
            }) => {
                let count = match count {
                    Count::Values(n) => n,
                    Count::Overflow(what) => {
                        return Some(Fault::strings(overflow(header, &format!("{what} strings"))));
                    }
                };
                let mut end = at + raw.len();
                // Ends with the lines: a count past them is a cut file.
                for met in 0..count {
                    let held = |more: &str| {
                        Fault::strings(format!(
                            "line {}: the string array `{}` holds {met} of its {count} strings{more}",
                            header.line, header.text
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
                strings.push(StringArray {
                    field: field.header,
                    field_arrays: field.arrays,
                    span: header.at..end,
                });
                declared.after_strings = Some((header, count));
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
        "char" | "unsigned_char" => 1,
        "short" | "unsigned_short" => 2,
        "int" | "unsigned_int" | "float" | "vtkidtype" => 4,
        "long" | "unsigned_long" | "double" | "vtktypeint64" | "vtktypeuint64" => 8,
        _ => return None,
    })
}

/// A binary file: each header's values are measured in bytes and skipped, and a section whose
/// bytes run past the end of the file is named; a string array's strings are skipped by their
/// lengths.
fn binary_walk<'a>(bytes: &'a [u8], v5: bool, strings: &mut Vec<StringArray<'a>>) -> Option<Fault> {
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
    let mut declared = Declared::default();
    loop {
        let after_strings = declared.after_strings;
        at = skip_blank(at);
        if at >= len {
            return None;
        }
        let end = line_end(at);
        let line = line_of(at);
        let text = match std::str::from_utf8(&bytes[at..end]) {
            Ok(text) if after_strings.is_none() || header_shaped(text) => text.trim(),
            // Not text: what follows cannot be told apart.
            _ => return after_strings.map(|strings| beyond(strings, line, &bytes[at..end])),
        };
        let header = Header { line, at, text };
        let mut data = (end + 1).min(len);
        if header.text.eq_ignore_ascii_case("METADATA") {
            // Lines of text, up to an empty one.
            while data < len {
                let raw = &bytes[data..line_end(data)];
                if let Some(strings) = after_strings
                    && (std::str::from_utf8(raw).is_err() || header_in_metadata(raw))
                {
                    return Some(unended(strings, line_of(data), raw));
                }
                data = (data + raw.len() + 1).min(len);
                if empty_line(raw) {
                    break;
                }
            }
            metadata_of_strings(bytes, strings, at..data);
            at = data;
            continue;
        }
        match section(header, v5, &mut declared) {
            Err(fault) => return Some(fault),
            Ok(Step::Unknown) => return None,
            Ok(Step::NoData) => {}
            Ok(Step::Strings {
                strings: count,
                field,
            }) => {
                let count = match count {
                    Count::Values(n) => n,
                    Count::Overflow(what) => {
                        return Some(Fault::strings(overflow(header, &format!("{what} strings"))));
                    }
                };
                // Each string takes a byte at least: the loop ends with the file.
                for met in 0..count {
                    let fault = |what: String| {
                        Some(Fault::strings(format!(
                            "line {}: the string array `{}`: string {} of {count} {what} (a \
                             wrong count or length, or the file is cut)",
                            header.line,
                            header.text,
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
                    return Some(Fault::strings(format!(
                        "line {}: the string array `{}`: its {count} strings end at byte {data}, \
                         where VTK writes a line end, not {} (a wrong count or length?)",
                        header.line,
                        header.text,
                        crate::excerpt(&bytes[data..(data + 12).min(len)], 12)
                    )));
                }
                strings.push(StringArray {
                    field: field.header,
                    field_arrays: field.arrays,
                    span: at..data,
                });
                declared.after_strings = Some((header, count));
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
            }
        }
        at = data;
    }
}
