//! CSV points in, CSV results out (and back in, for tests and scripts).

use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

use cgcontact::{Answer, CellId, GapAnswer, Hit};
use glam::DVec3;

use crate::{CellMap, ErrorKind, IoError};

/// The results file's header: the contract's five columns, then ours.
pub const RESULTS_HEADER: [&str; 8] = [
    "point",
    "cell",
    "xi",
    "eta",
    "zeta",
    "iterations",
    "residual",
    "inversions",
];

/// Read query points from a CSV file: three columns x, y, z; an optional header line.
///
/// The first row is a header when none of its fields is a number (`x,y,z`, say). A header that
/// names x, y and z in another order (`z,y,x`) is followed: each column is read as the axis it
/// names. Blank lines and
/// lines starting with `#` are skipped; fields may be padded with spaces. NaN and infinite values
/// (`nan`, `inf`) are read as such, so the library can answer for each point; a field that is not a
/// number, a finite number beyond f64's range (`1e400`, which would read as infinite), or a row
/// without exactly 3 fields, is an error naming its 1-based line. A file without data rows is an
/// error.
pub fn read_points(path: impl AsRef<Path>) -> Result<Vec<DVec3>, IoError> {
    read_with(path.as_ref(), points_from_bytes)
}

/// [`read_points`], and the warning [`unended_points_file`] gives, from one read of the file: a
/// named pipe or a process substitution (`<(zcat points.csv.gz)`) can be read only once.
///
/// # Errors
///
/// As [`read_points`].
pub fn read_points_with_warning(
    path: impl AsRef<Path>,
) -> Result<(Vec<DVec3>, Option<String>), IoError> {
    let path = path.as_ref();
    read_with(path, |bytes| {
        let points = points_from_bytes(bytes)?;
        Ok((points, unended_warning(path, bytes)))
    })
}

/// A warning for a points file that ends in a value with no line end after it: a file cut inside
/// its last number reads as another number (`0.0123456789` cut to `0.012`), and only the missing
/// line end tells. `None` when the file ends in whitespace, is empty, is not a regular file or
/// cannot be read. The file is opened again: a named pipe, which could not be read again (opening
/// it waited for a writer for ever), is not opened; [`read_points_with_warning`] reads the points
/// and gives the warning from one read.
#[must_use]
pub fn unended_points_file(path: impl AsRef<Path>) -> Option<String> {
    let path = path.as_ref();
    // Told without opening the file: opening a named pipe waits for a writer.
    let meta = std::fs::metadata(path).ok()?;
    let len = meta.len();
    if !meta.is_file() || len == 0 {
        return None;
    }
    let mut file = std::fs::File::open(path).ok()?;
    let tail = len.min(64);
    file.seek(SeekFrom::Start(len - tail)).ok()?;
    let mut bytes = vec![0; tail as usize];
    file.read_exact(&mut bytes).ok()?;
    unended_warning(path, &bytes)
}

/// The warning of [`unended_points_file`] for the file at `path` whose last bytes are `tail`.
fn unended_warning(path: &Path, tail: &[u8]) -> Option<String> {
    if tail.last()?.is_ascii_whitespace() {
        return None;
    }
    let word = tail
        .iter()
        .rposition(|&b| b.is_ascii_whitespace() || b == b',')
        .map_or(0, |i| i + 1);
    Some(format!(
        "{}: the file ends in {} with no line end after it: if it was cut inside that value, \
         the last point is not the one written (add the line end if the file is whole)",
        path.display(),
        crate::excerpt(&tail[word..], 40)
    ))
}

/// Read `path` (within the input size limit, refused at once if binary) and parse it with `parse`,
/// naming the file in any error.
fn read_with<T>(
    path: &Path,
    parse: impl FnOnce(&[u8]) -> Result<T, ErrorKind>,
) -> Result<T, IoError> {
    let bytes = crate::input::read_input(path, crate::input::Expect::Text)?;
    parse(&bytes).map_err(|e| e.in_file(path))
}

/// [`read_points`] from any reader.
pub fn parse_points(mut reader: impl Read) -> Result<Vec<DVec3>, ErrorKind> {
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes)?;
    points_from_bytes(&bytes)
}

/// [`parse_points`] on the bytes of a whole file.
fn points_from_bytes(bytes: &[u8]) -> Result<Vec<DVec3>, ErrorKind> {
    let unix = unix_line_ends(bytes);
    let bytes: &[u8] = &unix;
    let mut lines = LineCounter::new(bytes);
    let mut csv = csv_reader(bytes);
    let mut points = Vec::new();
    let mut record = csv::StringRecord::new();
    let mut first = true;
    // The axis of each column: positional unless the header names the axes in another order.
    let mut columns = [0, 1, 2];
    while let Some(line) = next_record(&mut csv, &mut record, &mut lines)? {
        if first {
            first = false;
            // A first line with no number at all is a header, unless its fields are numbers
            // with a decimal comma (`"1,5","2,5","3,5"`): those get the rows' message.
            if record.iter().all(|f| f.parse::<f64>().is_err())
                && !record.iter().all(|f| decimal_comma(f).is_some())
            {
                if record.len() != 3 {
                    return Err(ErrorKind::Csv {
                        line,
                        message: wrong_field_count(&record, "header"),
                    });
                }
                columns =
                    header_axes(&record).map_err(|message| ErrorKind::Csv { line, message })?;
                continue;
            }
        }
        if record.len() != 3 {
            return Err(ErrorKind::Csv {
                line,
                message: wrong_field_count(&record, "row"),
            });
        }
        let mut xyz = [0.0; 3];
        for (field, text) in record.iter().enumerate() {
            xyz[columns[field]] = coordinate(text).map_err(|what| ErrorKind::Csv {
                line,
                message: format!(
                    "field {} ({}) {what}",
                    field + 1,
                    crate::excerpt(text.as_bytes(), 32)
                ),
            })?;
        }
        points.push(DVec3::from_array(xyz));
    }
    if points.is_empty() {
        return Err(ErrorKind::Empty);
    }
    Ok(points)
}

/// A coordinate of a points file: a number, `nan` or `inf` (any case, signed). A finite number
/// beyond f64's range (`1e400`), which Rust's parser rounds to infinity, is refused rather than
/// read as an infinite point: the file holds a value the program cannot, not an infinity. A
/// number written with a decimal comma (`"1,5"`, as spreadsheets write in many locales) is
/// refused with the number it would be.
fn coordinate(text: &str) -> Result<f64, String> {
    let value: f64 = text.parse().map_err(|_| match decimal_comma(text) {
        Some(point) => {
            format!("is not a number (a decimal comma? write `{point}`)")
        }
        None => "is not a number".to_owned(),
    })?;
    if value.is_infinite() && !text.to_ascii_lowercase().contains("inf") {
        return Err("is beyond the range of f64 (magnitudes up to 1.8e308)".to_owned());
    }
    Ok(value)
}

/// `text` with its one comma made a decimal point, when that makes it a finite number written
/// with digits on both sides of the comma (`1,5`, `-0,25e3`), as a decimal-comma locale writes
/// one; `None` otherwise (`1,000,000`, `,5`, `x,y`).
fn decimal_comma(text: &str) -> Option<String> {
    let text = text.trim();
    let (whole, fraction) = text.split_once(',')?;
    let digit_ends = whole.ends_with(|c: char| c.is_ascii_digit())
        && fraction.starts_with(|c: char| c.is_ascii_digit());
    let point = format!("{whole}.{fraction}");
    (digit_ends && !fraction.contains(',') && point.parse::<f64>().is_ok_and(f64::is_finite))
        .then_some(point)
}

/// The axis each column of a points file holds, from its 3-field header: x, y and z in any order
/// (case and padding aside) are read by name; a header that names no axis out of its column
/// (`x,y,z`, `a,b,c`, `x,y,depth`) is read by position. A header that names an axis out of its
/// column without naming all three once (`y,x,depth`, `x,x,z`) is an error: read by position,
/// it would swap coordinates without a word. A name may be quoted, after spaces too (`"x", "z",
/// "y"`: the CSV reader unquotes a field only when the quote is its first byte) and in single
/// quotes: read as unnamed, such a header's columns were taken by position. A name may carry a
/// unit or qualifier beyond a separator (`x_mm`, `X [m]`, `pos_x`).
fn header_axes(header: &csv::StringRecord) -> Result<[usize; 3], String> {
    let axis = |field: &str| {
        let name = field.trim();
        let name = ['"', '\'']
            .iter()
            .find_map(|&q| name.strip_prefix(q)?.strip_suffix(q))
            .unwrap_or(name);
        let name = name.trim().as_bytes();
        let axis_of = |c: u8| match c.to_ascii_lowercase() {
            b'x' => Some(0),
            b'y' => Some(1),
            b'z' => Some(2),
            _ => None,
        };
        // The name alone, or the name and a unit or qualifier after a separator (`x_mm`,
        // `X [m]`, `y(mm)`, `z/m`), or a qualifier and the name (`pos_x`, `coord.y`): read
        // by position, `x_mm,z_mm,y_mm` swapped y and z without a word. A name whose two ends
        // name different axes (`x_y`) names none.
        let decorated = |c: &u8| !c.is_ascii_alphanumeric();
        let first = match name {
            [c] => axis_of(*c),
            [c, next, ..] if decorated(next) => axis_of(*c),
            _ => None,
        };
        let last = match name {
            [.., before, c] if decorated(before) => axis_of(*c),
            _ => None,
        };
        match (first, last) {
            (Some(a), Some(b)) if a != b => None,
            (a, b) => a.or(b),
        }
    };
    let named: Vec<Option<usize>> = header.iter().map(axis).collect();
    let mut seen = [false; 3];
    let permutation = named
        .iter()
        .all(|a| a.is_some_and(|a| !std::mem::replace(&mut seen[a], true)));
    if permutation {
        return Ok([0, 1, 2].map(|k| named[k].unwrap_or(k)));
    }
    if named
        .iter()
        .enumerate()
        .all(|(k, a)| a.is_none_or(|a| a == k))
    {
        return Ok([0, 1, 2]);
    }
    let fields: Vec<String> = header
        .iter()
        .map(|f| crate::excerpt(f.as_bytes(), 16))
        .collect();
    Err(format!(
        "header {} names the axes out of their columns without naming x, y and z once each: \
         name all three, in any order, or none",
        fields.join(",")
    ))
}

/// A number as the CSV files write it: the shortest digits that read back bitwise, in plain
/// decimals from 1e-4 to below 1e16 (and 0, NaN, inf), in exponent form beyond (as Python's
/// `repr`). Plain decimals alone wrote 5e-324 in 327 characters and 1e300 in 301.
#[derive(Clone, Copy, Debug)]
pub struct Num(pub f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let m = self.0.abs();
        if m == 0.0 || !m.is_finite() || (1e-4..1e16).contains(&m) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

/// Write points as CSV with header `x,y,z` (shortest round-trip form: read back bitwise).
pub fn write_points(path: impl AsRef<Path>, points: &[DVec3]) -> Result<(), IoError> {
    crate::atomic::write_file(path, |out| {
        writeln!(out, "x,y,z")?;
        for p in points {
            writeln!(out, "{},{},{}", Num(p.x), Num(p.y), Num(p.z))?;
        }
        Ok(())
    })
}

/// One row of a results file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResultRow {
    /// 0-based row of the points file.
    pub point: usize,
    /// Input mesh cell index, or `None` when not located (−1 in the file).
    pub cell: Option<usize>,
    /// Local coordinates (ξ, η, ζ), NaN when not located.
    pub xi: DVec3,
    /// Newton iterations of the accepted inversion (0 when not located).
    pub iterations: u32,
    /// Residual |x − x(ξ)| (NaN when not located).
    pub residual: f64,
    /// Newton inversions tried for the point, failed ones included (for a point not located: the
    /// count its strategy reported, 0 where none was).
    pub inversions: u32,
}

/// Write results as CSV: header [`RESULTS_HEADER`], one row per answer, `cell` as the input mesh's
/// cell index (via `cells`) or −1, floating point values in shortest round-trip form. A point not
/// located has ξ and the residual `NaN`, 0 iterations, and 0 inversions (see [`write_results_counted`]
/// for the inversions its search tried).
pub fn write_results(
    path: impl AsRef<Path>,
    answers: &[Answer],
    cells: &CellMap,
) -> Result<(), IoError> {
    crate::atomic::write_file(path, |out| Ok(write_results_to(out, answers, cells)?))
}

/// [`write_results`] with the Newton inversions each point's search tried, failed ones included
/// (`Locator::locate_counted`), so that points not located carry their cost too.
pub fn write_results_counted(
    path: impl AsRef<Path>,
    answers: &[Answer],
    tried: &[u32],
    cells: &CellMap,
) -> Result<(), IoError> {
    crate::atomic::write_file(path, |out| {
        Ok(write_rows(out, answers, Some(tried), cells)?)
    })
}

/// [`write_results`] to any writer.
pub fn write_results_to(
    out: impl Write,
    answers: &[Answer],
    cells: &CellMap,
) -> std::io::Result<()> {
    write_rows(out, answers, None, cells)
}

fn write_rows(
    mut out: impl Write,
    answers: &[Answer],
    tried: Option<&[u32]>,
    cells: &CellMap,
) -> std::io::Result<()> {
    writeln!(out, "{}", RESULTS_HEADER.join(","))?;
    for (point, answer) in answers.iter().enumerate() {
        match answer {
            Ok(Some(hit)) => {
                let cell = cells.input_cell(hit.cell).map_or(-1, |c| c as i64);
                hit_row(&mut out, point, cell, hit, "")?;
            }
            Ok(None) | Err(_) => {
                let inversions = tried.and_then(|t| t.get(point)).copied().unwrap_or(0);
                writeln!(out, "{point},-1,NaN,NaN,NaN,0,NaN,{inversions}")?;
            }
        }
    }
    Ok(())
}

/// One results row of a located point: `point,cell,xi,eta,zeta,iterations,residual,inversions`,
/// then `tail` (the gap columns, each with its comma, or nothing).
fn hit_row(
    mut out: impl Write,
    point: usize,
    cell: i64,
    hit: &Hit,
    tail: &str,
) -> std::io::Result<()> {
    writeln!(
        out,
        "{point},{cell},{},{},{},{},{},{}{tail}",
        Num(hit.xi.x),
        Num(hit.xi.y),
        Num(hit.xi.z),
        hit.iterations,
        Num(hit.residual),
        hit.inversions
    )
}

/// Read a results file (header first; the columns after `zeta` are optional).
pub fn read_results(path: impl AsRef<Path>) -> Result<Vec<ResultRow>, IoError> {
    read_with(path.as_ref(), results_from_bytes)
}

/// [`read_results`] from any reader.
pub fn parse_results(mut reader: impl Read) -> Result<Vec<ResultRow>, ErrorKind> {
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes)?;
    results_from_bytes(&bytes)
}

/// [`parse_results`] on the bytes of a whole file.
fn results_from_bytes(bytes: &[u8]) -> Result<Vec<ResultRow>, ErrorKind> {
    let unix = unix_line_ends(bytes);
    let bytes: &[u8] = &unix;
    let mut lines = LineCounter::new(bytes);
    let mut csv = csv_reader(bytes);
    let mut record = csv::StringRecord::new();
    let header_line = next_record(&mut csv, &mut record, &mut lines)?.ok_or(ErrorKind::Empty)?;
    let names: Vec<String> = record.iter().map(str::to_owned).collect();
    if names.len() < 5 || names[..5] != RESULTS_HEADER[..5] {
        return Err(ErrorKind::Csv {
            line: header_line,
            message: format!(
                "header {} does not start with point,cell,xi,eta,zeta",
                crate::excerpt(names.join(",").as_bytes(), 60)
            ),
        });
    }
    let column = |name: &str| names.iter().position(|n| n == name);
    let (iterations, residual, inversions) = (
        column("iterations"),
        column("residual"),
        column("inversions"),
    );
    let mut rows = Vec::new();
    while let Some(line) = next_record(&mut csv, &mut record, &mut lines)? {
        if record.len() != names.len() {
            return Err(ErrorKind::Csv {
                line,
                message: format!("{} fields, the header has {}", record.len(), names.len()),
            });
        }
        let field = |i: usize| record.get(i).unwrap_or("");
        let bad = |i: usize| ErrorKind::Csv {
            line,
            message: format!(
                "{} {} is not valid",
                names[i],
                crate::excerpt(field(i).as_bytes(), 32)
            ),
        };
        let point = field(0).parse::<usize>().map_err(|_| bad(0))?;
        let cell = match field(1).parse::<i64>().map_err(|_| bad(1))? {
            -1 => None,
            c if c >= 0 => Some(c as usize),
            _ => return Err(bad(1)),
        };
        let f = |i: usize| field(i).parse::<f64>().map_err(|_| bad(i));
        let xi = DVec3::new(f(2)?, f(3)?, f(4)?);
        // Optional columns may be empty (no value for that row).
        let optional_u32 = |i: Option<usize>| -> Result<u32, ErrorKind> {
            match i {
                Some(i) if !field(i).is_empty() => field(i).parse().map_err(|_| bad(i)),
                _ => Ok(0),
            }
        };
        let residual = match residual {
            Some(i) if !field(i).is_empty() => f(i)?,
            _ => f64::NAN,
        };
        rows.push(ResultRow {
            point,
            cell,
            xi,
            iterations: optional_u32(iterations)?,
            residual,
            inversions: optional_u32(inversions)?,
        });
    }
    Ok(rows)
}

/// `bytes` with each line end that is a `\r` alone (classic Mac files) made a `\n`, byte for
/// byte, so that offsets stay: the csv crate ends a `#` comment only at `\n`, so such a comment
/// swallowed the rest of the file, and lines are counted by `\n`.
fn unix_line_ends(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    let lone = |i: usize| bytes[i] == b'\r' && bytes.get(i + 1) != Some(&b'\n');
    if !(0..bytes.len()).any(lone) {
        return std::borrow::Cow::Borrowed(bytes);
    }
    let mut unix = bytes.to_vec();
    for (i, byte) in unix.iter_mut().enumerate() {
        if lone(i) {
            *byte = b'\n';
        }
    }
    std::borrow::Cow::Owned(unix)
}

fn csv_reader(reader: impl Read) -> csv::Reader<impl Read> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(reader)
}

/// 1-based line numbers from byte offsets.
///
/// The csv crate's own line count leaves out the blank and comment lines it skips, so we count
/// newlines up to each record's byte offset ourselves (forward only: linear in the file).
struct LineCounter<'a> {
    bytes: &'a [u8],
    at: usize,
    line: u64,
}

impl<'a> LineCounter<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self {
            bytes,
            at: 0,
            line: 1,
        }
    }

    fn line_of_byte(&mut self, byte: u64) -> u64 {
        let byte = usize::try_from(byte)
            .unwrap_or(usize::MAX)
            .min(self.bytes.len());
        if byte < self.at {
            // Not expected (records come in order); count afresh.
            self.at = 0;
            self.line = 1;
        }
        self.line += self.bytes[self.at..byte]
            .iter()
            .filter(|&&b| b == b'\n')
            .count() as u64;
        self.at = byte;
        self.line
    }

    /// The line a record starts on. Its position is where the reader stopped after the previous
    /// record, before the blank and `#` lines it then skipped: skip those too.
    fn line_at(&mut self, record: &csv::StringRecord) -> u64 {
        let Some(position) = record.position() else {
            return 0;
        };
        let mut at = usize::try_from(position.byte())
            .unwrap_or(usize::MAX)
            .min(self.bytes.len());
        loop {
            let rest = &self.bytes[at..];
            let skip = match rest.first() {
                Some(b'\n') => 1,
                Some(b'\r') if rest.get(1) == Some(&b'\n') => 2,
                Some(b'\r') => 1,
                Some(b'#') => rest
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(rest.len(), |i| i + 1),
                _ => 0,
            };
            if skip == 0 {
                break;
            }
            at += skip;
        }
        self.line_of_byte(at as u64)
    }
}

/// Reads the next record into `record`: the line it starts on, or `None` at the end of the data.
fn next_record(
    csv: &mut csv::Reader<impl Read>,
    record: &mut csv::StringRecord,
    lines: &mut LineCounter<'_>,
) -> Result<Option<u64>, ErrorKind> {
    loop {
        match csv.read_record(record) {
            // A line of spaces only is a blank line (docs/formats.md): skipped like an empty one.
            Ok(true) if record.len() == 1 && record[0].is_empty() => {}
            Ok(true) => return Ok(Some(lines.line_at(record))),
            Ok(false) => return Ok(None),
            Err(e) => return Err(csv_error(&e, lines)),
        }
    }
}

/// Why a points row or header does not have the 3 fields x,y,z, in words: another separator is
/// named (`1;2;3` is one field for a comma-separated reader; `1 2 3`, numpy's `savetxt`
/// default, too: fields are trimmed, so a space left inside one separates values). Such a line
/// is not called a header: its values are not numbers only because they are not split.
fn wrong_field_count(record: &csv::StringRecord, what: &str) -> String {
    let separator = [';', '\t', '|', ' ']
        .into_iter()
        .find(|&c| record.len() < 3 && record.iter().any(|f| f.contains(c)));
    match separator {
        Some(c) => format!(
            "values separated by {}, expected commas (x,y,z)",
            match c {
                '\t' => "tabs".to_owned(),
                ' ' => "spaces".to_owned(),
                c => format!("`{c}`"),
            }
        ),
        None => format!(
            "{what} with {} field{}, expected 3 (x,y,z)",
            record.len(),
            if record.len() == 1 { "" } else { "s" }
        ),
    }
}

fn csv_error(e: &csv::Error, lines: &mut LineCounter<'_>) -> ErrorKind {
    let line = e.position().map_or(0, |p| lines.line_of_byte(p.byte()));
    match e.kind() {
        csv::ErrorKind::Utf8 { .. } => ErrorKind::Csv {
            line,
            message: "not valid UTF-8 text".to_owned(),
        },
        csv::ErrorKind::Io(io) => ErrorKind::Csv {
            line,
            message: format!("read error: {io}"),
        },
        _ => ErrorKind::Csv {
            line,
            message: e.to_string(),
        },
    }
}

/// Write the results of `locate --all-owners`: the header and columns of the usual results file
/// ([`write_results_counted`]), but one row per owner of each point, the point's
/// index repeated, cells ascending in the input mesh's numbering (`input_cell` maps the locator's
/// cell ids to it), each row with that owner's ξ, iterations, residual and the inversions the
/// search had tried when it found it. A point with no owner (outside, or refused) keeps its one
/// row as the usual file writes it: `point,-1,NaN,NaN,NaN,0,NaN,tried`. One hit per point gives
/// the usual file. With `gaps` (`locate --gap`), every row of point p ends with p's
/// [`GAP_HEADER`] columns, empty where its surface is farther than the search distance.
pub fn write_owner_rows<'a>(
    path: impl AsRef<Path>,
    owners: impl Iterator<Item = &'a [Hit]>,
    tried: &[u32],
    input_cell: impl Fn(CellId) -> Option<usize>,
    gaps: Option<&[GapAnswer]>,
) -> Result<(), IoError> {
    crate::write_file(path, |out| {
        write!(out, "{}", RESULTS_HEADER.join(","))?;
        if gaps.is_some() {
            write!(out, ",{}", GAP_HEADER.join(","))?;
        }
        writeln!(out)?;
        // The gap columns of each point, in one buffer rewritten for each.
        let mut gap = String::new();
        // Reused for every point: at most a few owners each, sorted by their input cell.
        let mut rows: Vec<(i64, &Hit)> = Vec::new();
        for (point, hits) in owners.enumerate() {
            if let Some(gaps) = gaps {
                gap_columns(&mut gap, gaps.get(point), &input_cell);
            }
            if hits.is_empty() {
                let inversions = tried.get(point).copied().unwrap_or(0);
                writeln!(out, "{point},-1,NaN,NaN,NaN,0,NaN,{inversions}{gap}")?;
                continue;
            }
            rows.clear();
            rows.extend(
                hits.iter()
                    .map(|hit| (input_cell(hit.cell).map_or(-1, |c| c as i64), hit)),
            );
            // The locator sorts by its own ids (lattice cells); the file names input cells.
            rows.sort_by_key(|&(cell, _)| cell);
            for &(cell, hit) in &rows {
                hit_row(&mut *out, point, cell, hit, &gap)?;
            }
        }
        Ok(())
    })
}

/// Writes into `buf` (cleared first) the gap columns of a point of answer `gap`, each preceded by
/// its comma: empty where the surface is farther than the search distance or the point was
/// refused; `face_cell` in the input numbering (`input_cell`).
fn gap_columns(
    buf: &mut String,
    gap: Option<&GapAnswer>,
    input_cell: &impl Fn(CellId) -> Option<usize>,
) {
    use std::fmt::Write as _;
    buf.clear();
    match gap {
        Some(Ok(Some(c))) => {
            let face_cell = input_cell(c.face.cell).map_or(-1, |i| i as i64);
            write!(
                buf,
                ",{},{},{},{},{},{},{},{face_cell},{}",
                Num(c.gap),
                Num(c.point.x),
                Num(c.point.y),
                Num(c.point.z),
                Num(c.normal.x),
                Num(c.normal.y),
                Num(c.normal.z),
                c.face.local
            )
            .expect("writing to a String cannot fail");
        }
        _ => {
            buf.extend(std::iter::repeat_n(',', GAP_HEADER.len()));
        }
    }
}

/// The columns `locate --gap` appends to each results row.
pub const GAP_HEADER: [&str; 9] = [
    "gap",
    "cx",
    "cy",
    "cz",
    "nx",
    "ny",
    "nz",
    "face_cell",
    "face",
];
