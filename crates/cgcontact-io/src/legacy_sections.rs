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

/// A section's header line and its 1-based number.
#[derive(Clone, Copy)]
struct Header<'a> {
    line: usize,
    text: &'a str,
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
    /// A header with no values of its own (`DATASET`, `POINT_DATA n`, `FIELD name n`, ...).
    NoData,
    /// A line this walk does not know.
    Unknown,
}

/// The first section at fault in a legacy file that vtkio's parser refused, as
/// `line N: what is wrong`; `None` when none is found (the parser's own message is then used).
pub(crate) fn fault(bytes: &[u8]) -> Option<String> {
    let mut lines = bytes.split(|&b| b == b'\n');
    // Version 5.x lists cells as OFFSETS and CONNECTIVITY under a CELLS line.
    let v5 = lines.next()?.windows(9).any(|w| w == b"Version 5");
    lines.next()?;
    let kind = lines.next()?.trim_ascii();
    if kind.eq_ignore_ascii_case(b"ascii") {
        ascii_fault(std::str::from_utf8(bytes).ok()?, v5)
    } else if kind.eq_ignore_ascii_case(b"binary") {
        binary_fault(bytes, v5)
    } else {
        None
    }
}

/// Reads one header line; `Err` names a `POINT_DATA` or `CELL_DATA` count that is not the
/// file's.
fn section<'a>(
    header: Header<'a>,
    v5: bool,
    declared: &mut Declared<'a>,
) -> Result<Step<'a>, String> {
    let mut words = header.text.split_whitespace();
    let Some(keyword) = words.next() else {
        return Ok(Step::Unknown);
    };
    let count = |word: Option<&str>| word.and_then(|n| n.parse::<u64>().ok());
    let data = |values, kind| Step::Data {
        values,
        kind,
        scalars: false,
    };
    Ok(match keyword.to_ascii_uppercase().as_str() {
        "DATASET" | "FIELD" => Step::NoData,
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
                    return Err(format!(
                        "line {}: `{}` does not match the {expected} {what} that `{}` (line {}) \
                         declares",
                        header.line, header.text, by.text, by.line
                    ));
                }
                declared.tuples = n;
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
                data(product(components, tuples), Some(kind))
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

/// An ASCII file: the values of each section are counted against its header.
fn ascii_fault(text: &str, v5: bool) -> Option<String> {
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
            format!(
                "line {}: the `{}` section holds {} of its {} values ({hint})",
                open.header.line, open.header.text, open.found, open.expected
            )
        })
    };
    let mut declared = Declared::default();
    let mut current: Option<Open> = None;
    let mut offset = 0;
    // The first three lines are the version, the title (anything) and `ASCII`.
    for (index, raw) in text.split_inclusive('\n').enumerate() {
        offset += raw.len();
        if index < 3 {
            continue;
        }
        let line = raw.trim();
        let Some(first) = line.split_whitespace().next() else {
            continue;
        };
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
        if let Some(message) = current.take().and_then(short) {
            return Some(message);
        }
        let header = Header {
            line: index + 1,
            text: line,
        };
        current = match section(header, v5, &mut declared) {
            Err(message) => return Some(message),
            Ok(Step::Data {
                values: Count::Overflow(what),
                ..
            }) => return Some(overflow(header, &format!("{what} values"))),
            Ok(Step::Data {
                values: Count::Values(expected),
                scalars,
                ..
            }) => Some(Open {
                header,
                expected,
                found: 0,
                room: text.len() - offset,
                scalars,
            }),
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
/// bytes run past the end of the file is named.
fn binary_fault(bytes: &[u8], v5: bool) -> Option<String> {
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
        at = skip_blank(at);
        if at >= len {
            return None;
        }
        let end = line_end(at);
        let header = Header {
            line: line_of(at),
            text: std::str::from_utf8(&bytes[at..end]).ok()?.trim(),
        };
        let mut data = (end + 1).min(len);
        match section(header, v5, &mut declared) {
            Err(message) => return Some(message),
            Ok(Step::Unknown) => return None,
            Ok(Step::NoData) => {}
            Ok(Step::Data {
                values,
                kind,
                scalars,
            }) => {
                let values = match values {
                    Count::Values(n) => n,
                    Count::Overflow(what) => {
                        return Some(overflow(header, &format!("{what} values")));
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
                    return Some(overflow(header, &format!("{values} values × {size} bytes")));
                };
                let room = (len - data) as u64;
                if need > room {
                    return Some(format!(
                        "line {}: the `{}` section declares {values} values of {size} bytes, \
                         but only {room} bytes follow its header (a wrong count, or the file is \
                         cut)",
                        header.line, header.text
                    ));
                }
                data += need as usize;
            }
        }
        at = data;
    }
}
