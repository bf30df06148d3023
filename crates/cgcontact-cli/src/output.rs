//! What the tool writes: files (whole or not at all), standard output, and the checks that no output
//! replaces an input or fails after the work is done.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use cgcontact::{CellId, GapAnswer, Hit};

/// Write `text` to `path`, whole or not at all.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    cgcontact_io::write_file(path, |out| Ok(out.write_all(text.as_bytes())?))?;
    Ok(())
}

/// Write the results of `locate --all-owners`: the header and columns of the usual results file
/// (`cgcontact_io::write_results_counted`), but one row per owner of each point, the point's
/// index repeated, cells ascending in the input mesh's numbering (`input_cell` maps the locator's
/// cell ids to it), each row with that owner's ξ, iterations, residual and the inversions the
/// search had tried when it found it. A point with no owner (outside, or refused) keeps its one
/// row as the usual file writes it: `point,-1,NaN,NaN,NaN,0,NaN,tried`. One hit per point gives
/// the usual file. With `gaps` (`locate --gap`), every row of point p ends with p's
/// [`GAP_HEADER`] columns, empty where its surface is farther than the search distance.
pub fn write_owner_rows<'a>(
    path: &Path,
    owners: impl Iterator<Item = &'a [Hit]>,
    tried: &[u32],
    input_cell: impl Fn(CellId) -> Option<usize>,
    gaps: Option<&[GapAnswer]>,
) -> Result<()> {
    cgcontact_io::write_file(path, |out| {
        write!(out, "{}", cgcontact_io::RESULTS_HEADER.join(","))?;
        if gaps.is_some() {
            write!(out, ",{}", GAP_HEADER.join(","))?;
        }
        writeln!(out)?;
        // The gap columns of point p: empty where the surface is farther than D.
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
            for (cell, hit) in &rows {
                writeln!(
                    out,
                    "{point},{cell},{},{},{},{},{},{}{gap}",
                    hit.xi.x, hit.xi.y, hit.xi.z, hit.iterations, hit.residual, hit.inversions
                )?;
            }
        }
        Ok(())
    })?;
    Ok(())
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
                c.gap,
                c.point.x,
                c.point.y,
                c.point.z,
                c.normal.x,
                c.normal.y,
                c.normal.z,
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

/// Standard output could not be written. A closed pipe (`cgcontact ... | head -c 1`) is a normal end
/// of the program; anything else (a full disk) is an error.
#[derive(Debug)]
pub struct StdoutError(pub std::io::Error);

impl std::fmt::Display for StdoutError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cannot write to standard output: {}", self.0)
    }
}

impl std::error::Error for StdoutError {}

impl StdoutError {
    /// The reader went away: nothing to report.
    pub fn is_closed_pipe(&self) -> bool {
        self.0.kind() == std::io::ErrorKind::BrokenPipe
    }
}

/// Write `text` and a newline to standard output, flushed.
pub fn print_line(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}")
        .and_then(|()| out.flush())
        .map_err(|e| StdoutError(e).into())
}

/// `println!` that returns an error instead of panicking when standard output fails.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::output::print_line(&format!($($arg)*))
    };
}
pub(crate) use say;

/// The file a path names, for comparing: its canonical form when it exists, else its folder's
/// canonical form joined with its name (the folder must exist).
fn identity(path: &Path) -> Option<PathBuf> {
    if let Ok(canonical) = std::fs::canonicalize(path) {
        return Some(canonical);
    }
    let name = path.file_name()?;
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(folder).ok()?.join(name))
}

/// Whether two paths name the same file: the same canonical path, or (on Unix) the same device and
/// inode (hard links).
fn same_file(a: &Path, b: &Path) -> bool {
    if let (Some(x), Some(y)) = (identity(a), identity(b))
        && x == y
    {
        return true;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
    }
    false
}

/// Check, before any work, that every output file can be written where asked and replaces no
/// input: `outputs` are (flag, path) pairs, `inputs` likewise.
pub fn check_outputs(inputs: &[(&str, &Path)], outputs: &[(&str, PathBuf)]) -> Result<()> {
    for (flag, output) in outputs {
        for (input_flag, input) in inputs {
            if same_file(output, input) {
                bail!(
                    "{}: {flag} would overwrite the input {input_flag} {} (the same file); choose another output",
                    output.display(),
                    input.display()
                );
            }
        }
        if output.is_dir() {
            bail!("{}: {flag} names a folder, not a file", output.display());
        }
        let folder = match output.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        if !folder.is_dir() {
            bail!(
                "{}: {flag}: the folder {} does not exist",
                output.display(),
                folder.display()
            );
        }
        // A folder we cannot write to fails now, not after the work (devices are written in place).
        if !output.exists() || output.is_file() {
            tempfile::tempfile_in(folder).map_err(|e| {
                anyhow::anyhow!(
                    "{}: {flag}: cannot write in {}: {e}",
                    output.display(),
                    folder.display()
                )
            })?;
        }
    }
    Ok(())
}

/// Check that `dir` (a `--vtk` or `--out` folder) is a folder or can be made one, and create it.
pub fn prepare_folder(flag: &str, dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        bail!("{}: {flag} names a file, not a folder", dir.display());
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("{}: {flag}: cannot create the folder: {e}", dir.display()))?;
    // A folder we cannot write to fails now, not after the work.
    tempfile::tempfile_in(dir).map_err(|e| {
        anyhow::anyhow!(
            "{}: {flag}: cannot write in this folder: {e}",
            dir.display()
        )
    })?;
    Ok(())
}
