//! What the tool writes: files (whole or not at all), standard output, and the checks that no output
//! replaces an input or fails after the work is done.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

use anyhow::{Result, bail};
use cgcontact_io::same_file;

/// Write `text` to `path`, whole or not at all.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    cgcontact_io::write_file(path, |out| Ok(out.write_all(text.as_bytes())?))?;
    Ok(())
}

pub use cgcontact_io::write_owner_rows;

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

/// The longest file name the usual file systems take, in bytes (Linux's `NAME_MAX`).
const MAX_NAME_BYTES: usize = 255;

/// Check, before any work, that every output file can be written where asked and replaces no
/// input: `outputs` are (flag, path) pairs, `inputs` likewise.
pub fn check_outputs(inputs: &[(&str, &Path)], outputs: &[(&str, PathBuf)]) -> Result<()> {
    for (at, (flag, output)) in outputs.iter().enumerate() {
        // `new/`, `.` or `..` name a folder even where none exists yet: the write would fail
        // after the work with the system's bare "Not a directory".
        if names_a_folder(output) {
            bail!(
                "{}: {flag} names a folder, not a file; give a file name",
                output.display()
            );
        }
        // Two outputs on one file: the second would silently replace the first.
        if let Some((other_flag, other)) = outputs[..at]
            .iter()
            .find(|(_, other)| same_file(output, other))
        {
            // One flag's two files (a command's `--out` folder): name both files.
            if other_flag == flag {
                bail!(
                    "{}: the same file as {} (through a link), and {flag} writes both; \
                     choose another output",
                    output.display(),
                    other.display()
                );
            }
            bail!(
                "{}: {other_flag} and {flag} would both write this file; choose another output",
                output.display()
            );
        }
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
        // An open descriptor (`/dev/stdout`) is written through, in place: no folder to check.
        if cgcontact_io::descriptor(output).is_some() {
            continue;
        }
        // The write would fail after the work with "File name too long".
        if let Some(name) = output.file_name()
            && name.len() > MAX_NAME_BYTES
        {
            bail!(
                "{}: {flag}: the file name is {} bytes long, more than the {MAX_NAME_BYTES} a \
                 file system takes",
                output.display(),
                name.len()
            );
        }
        // A symbolic link is written through, its target made if it does not exist yet: in the
        // target's folder.
        let Some(target) = cgcontact_io::write_target(output) else {
            bail!(
                "{}: {flag}: symbolic links that lead back to themselves",
                output.display()
            );
        };
        let folder = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        if !folder.is_dir() {
            if target != *output {
                bail!(
                    "{}: {flag} is a symbolic link to {}, whose folder {} does not exist",
                    output.display(),
                    target.display(),
                    folder.display()
                );
            }
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
        // A file the write could not replace (read-only, another user's in `/tmp`) likewise.
        cgcontact_io::check_replaceable(output)
            .map_err(|e| anyhow::anyhow!("{}: {flag}: {}", output.display(), e.kind()))?;
    }
    Ok(())
}

/// Check, once the mesh file `mesh` is read and before its pieces are, that no output is one of
/// the files of its pieces (`pieces`, a parallel file's; none for a serial file): they are inputs
/// as much as `--mesh` is, compared as [`check_outputs`] compares those.
pub fn check_pieces(mesh: &Path, pieces: &[PathBuf], outputs: &[(&str, PathBuf)]) -> Result<()> {
    for (flag, output) in outputs {
        if let Some((piece, file)) = cgcontact_io::piece_file(output, pieces) {
            bail!(
                "{}: {flag} would overwrite {}, the file of piece {piece} of the input --mesh {} \
                 (the same file); choose another output",
                output.display(),
                file.display(),
                mesh.display()
            );
        }
    }
    Ok(())
}

/// Whether `path` can only name a folder: it ends with a separator, `.` or `..` (`Path` drops a
/// trailing `.`: `new/.` has the file name `new`).
fn names_a_folder(path: &Path) -> bool {
    let text = path.as_os_str().to_string_lossy();
    let text = text.strip_suffix('.').unwrap_or(&text);
    let text = text.strip_suffix('.').unwrap_or(text);
    path.file_name().is_none()
        || text.is_empty()
        || text.ends_with('/')
        || text.ends_with(std::path::MAIN_SEPARATOR)
}

/// Check that `dir` (a `--vtk` or `--out` folder) is a folder or can be made one, and create it.
/// The folders it made are removed again when the returned guard drops while they are still empty:
/// a run that fails before it writes anything leaves no empty folder behind.
pub fn prepare_folder(flag: &str, dir: &Path) -> Result<MadeFolders> {
    // `new/.` and `new/./` name the folder `new`, as `mkdir -p` takes them; the standard library's
    // `create_dir_all` asks for `new/.` before `new` exists and fails, and `new/.` could not be
    // removed again. Its components drop those dots (a leading `.` stays).
    let dir = &dir.components().collect::<PathBuf>();
    if dir.exists() && !dir.is_dir() {
        bail!("{}: {flag} names a file, not a folder", dir.display());
    }
    // The folders that do not exist yet, deepest first; known to the interrupt handler before
    // they are made.
    let made = MadeFolders(
        dir.ancestors()
            .filter(|a| !a.as_os_str().is_empty())
            .take_while(|a| std::fs::symlink_metadata(a).is_err())
            .map(Path::to_path_buf)
            .collect(),
    );
    made_folders().extend(made.0.iter().cloned());
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("{}: {flag}: cannot create the folder: {e}", dir.display()))?;
    // A folder we cannot write to fails now, not after the work.
    tempfile::tempfile_in(dir).map_err(|e| {
        anyhow::anyhow!(
            "{}: {flag}: cannot write in this folder: {e}",
            dir.display()
        )
    })?;
    Ok(made)
}

/// The folders [`prepare_folder`] made, deepest first; each one still empty when this drops is
/// removed.
#[must_use = "the folders are removed at once when this drops"]
pub struct MadeFolders(Vec<PathBuf>);

impl Drop for MadeFolders {
    fn drop(&mut self) {
        let mut all = made_folders();
        for folder in &self.0 {
            if let Some(at) = all.iter().rposition(|f| f == folder) {
                all.swap_remove(at);
            }
        }
        drop(all);
        for folder in &self.0 {
            // Fails, and keeps the folder, once anything was written in it.
            if std::fs::remove_dir(folder).is_err() {
                break;
            }
        }
    }
}

/// Every folder a [`MadeFolders`] still holds, for [`remove_made_folders`].
static MADE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn made_folders() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    MADE.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Removes the folders the run made that are still empty, deepest first: what the guards of
/// [`prepare_folder`] do when they drop, for a run ended by a signal, whose destructors do not
/// run. Call it after [`cgcontact_io::abandon_writes`], so that no write starts in them.
pub fn remove_made_folders() {
    remove_folders(made_folders().clone());
}

/// [`remove_made_folders`] for a run that cannot wait for the list: one that failed to allocate,
/// maybe while this thread held it. Gives up, leaving the folders, when the list is locked.
pub fn try_remove_made_folders() {
    match MADE.try_lock() {
        Ok(all) => remove_folders(all.clone()),
        Err(std::sync::TryLockError::Poisoned(e)) => remove_folders(e.into_inner().clone()),
        Err(std::sync::TryLockError::WouldBlock) => {}
    }
}

fn remove_folders(mut all: Vec<PathBuf>) {
    all.sort_by_key(|f| std::cmp::Reverse(f.components().count()));
    for folder in all {
        // Fails, and keeps the folder, where anything was written in it.
        let _ = std::fs::remove_dir(folder);
    }
}
