//! Files written whole or not at all.
//!
//! Every file this crate writes goes through [`write_file`]: the content goes to a temporary file
//! in the target's folder, which is flushed, synced and then renamed over the target. A failure
//! (a full disk, an error of the writer) removes the temporary file and leaves the target as it
//! was; a process killed mid-write leaves at most a hidden `.NAME.XXXXXX.partial` file beside an
//! intact target. A program that catches its interruption (Ctrl-C, `kill`) calls
//! [`abandon_writes`] before it exits, and leaves not even that. Devices, and paths to an open
//! descriptor (`/dev/stdout`: [`descriptor`]), are written in place.

use std::fs::OpenOptions;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use crate::{ErrorKind, IoError};

/// The temporary files being written now, by every thread. Held while a temporary file is renamed
/// over its target, so that [`abandon_writes`] sees each write either whole or not begun.
static IN_PROGRESS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn in_progress() -> MutexGuard<'static, Vec<PathBuf>> {
    // A writer that panicked left the list as valid as ever.
    IN_PROGRESS.lock().unwrap_or_else(|e| e.into_inner())
}

/// Remove the temporary file of every write in progress, and keep every write, in progress or
/// later, from reaching its target: for a program about to exit on an interruption (a signal
/// handler's thread). Each target is left as it was before its write, or complete. Returns how
/// many temporary files were removed.
///
/// Writes that call [`write_file`] afterwards wait forever before their rename: call this only
/// when the process exits next.
pub fn abandon_writes() -> usize {
    abandon(in_progress())
}

/// Removes the temporary files on the list `guard` holds, and keeps it locked.
fn abandon(guard: MutexGuard<'static, Vec<PathBuf>>) -> usize {
    let removed = guard
        .iter()
        .filter(|path| std::fs::remove_file(path).is_ok())
        .count();
    // The list stays locked until the process exits: no write begun before or after is renamed
    // over its target.
    std::mem::forget(guard);
    removed
}

/// [`abandon_writes`] for a program that cannot wait for the list of writes in progress: one that
/// failed to allocate memory, which may have failed while this very thread held the list (a write
/// registering its temporary file), so that waiting would never end. Tries for `patience`, then
/// gives up and returns `None`, leaving the temporary files where they are.
pub fn abandon_writes_within(patience: std::time::Duration) -> Option<usize> {
    let start = std::time::Instant::now();
    let guard = loop {
        match IN_PROGRESS.try_lock() {
            Ok(guard) => break guard,
            // A writer that panicked left the list as valid as ever.
            Err(std::sync::TryLockError::Poisoned(e)) => break e.into_inner(),
            Err(std::sync::TryLockError::WouldBlock) if start.elapsed() < patience => {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
            Err(std::sync::TryLockError::WouldBlock) => return None,
        }
    };
    Some(abandon(guard))
}

/// A temporary file on the [`IN_PROGRESS`] list while it lives. Dropped, it removes the file (if
/// it was not renamed) before it leaves the list, so that the file is never off the list and still
/// there.
struct Registered(PathBuf);

impl Drop for Registered {
    fn drop(&mut self) {
        let mut list = in_progress();
        // Gone already when renamed over its target.
        let _ = std::fs::remove_file(&self.0);
        if let Some(at) = list.iter().position(|p| *p == self.0) {
            list.swap_remove(at);
        }
    }
}

/// Write the file at `path` through `write`, atomically (see the module docs).
///
/// A symbolic link is written through (its target is replaced, not the link; a link whose target
/// does not exist yet makes it, in the target's folder: see [`write_target`]). A target that
/// exists and is not a regular file (`/dev/null`, a named pipe) is written in place, since there
/// is nothing there to keep. A folder is refused.
///
/// A path that leads to an open file descriptor ([`descriptor`]: `/dev/stdout`, `/dev/fd/N`,
/// `/proc/self/fd/N`) is written through that descriptor, never replaced: the file the shell
/// redirected it to (`> log`, `>> log`) keeps its inode and what it held, and the program's
/// later output follows in the same file. Standard output and standard error are written
/// through the program's own handles (at their offsets); any other descriptor is opened again
/// and appended to.
pub fn write_file(
    path: impl AsRef<Path>,
    write: impl FnOnce(&mut dyn Write) -> Result<(), ErrorKind>,
) -> Result<(), IoError> {
    let path = path.as_ref();
    let in_file = |kind: ErrorKind| kind.in_file(path);
    let io = |e: std::io::Error| ErrorKind::Io(e).in_file(path);
    if let Some(descriptor) = descriptor(path) {
        return match descriptor {
            Descriptor::Stdout => {
                let mut out = Recorder::new(BufWriter::new(std::io::stdout().lock()));
                finish(write(&mut out), out)
            }
            Descriptor::Stderr => {
                let mut out = Recorder::new(BufWriter::new(std::io::stderr().lock()));
                finish(write(&mut out), out)
            }
            Descriptor::Other(link) => {
                let file = OpenOptions::new().append(true).open(link).map_err(io)?;
                let mut out = Recorder::new(BufWriter::new(file));
                finish(write(&mut out), out)
            }
        }
        .map_err(in_file);
    }
    let target = write_target(path).ok_or_else(|| {
        in_file(ErrorKind::Mismatch(
            "symbolic links that lead back to themselves".to_owned(),
        ))
    })?;
    let existing = std::fs::metadata(&target).ok();
    if let Some(meta) = &existing {
        if meta.is_dir() {
            return Err(in_file(ErrorKind::Mismatch(
                "is a folder, not a file".to_owned(),
            )));
        }
        if meta.is_file() {
            replaceable(&target, meta).map_err(in_file)?;
        }
        if !meta.is_file() {
            let file = OpenOptions::new().write(true).open(&target).map_err(io)?;
            let mut out = Recorder::new(BufWriter::new(file));
            return finish(write(&mut out), out).map_err(in_file);
        }
    }
    let folder = folder_of(&target).to_path_buf();
    let prefix = temporary_prefix(target.file_name().unwrap_or_default());
    let mut builder = tempfile::Builder::new();
    builder
        .prefix(&prefix)
        .rand_bytes(TEMPORARY_RANDOM)
        .suffix(TEMPORARY_SUFFIX);
    // As `File::create` makes it (0666 less the umask), not the temporary file's usual 0600.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    // Made under the list's lock, and on the list until it is renamed or removed: after
    // `abandon_writes`, no temporary file is made.
    let (mut temp, _registered) = {
        let mut list = in_progress();
        let temp = builder.tempfile_in(&folder).map_err(io)?;
        let path = temp.path().to_path_buf();
        list.push(path.clone());
        (temp, Registered(path))
    };
    {
        let mut out = Recorder::new(BufWriter::new(temp.as_file_mut()));
        finish(write(&mut out), out).map_err(in_file)?;
    }
    temp.as_file().sync_all().map_err(io)?;
    if let Some(meta) = existing {
        // Keep the replaced file's permissions.
        temp.as_file()
            .set_permissions(meta.permissions())
            .map_err(io)?;
    }
    // Renamed only while no `abandon_writes` runs (it never releases the list).
    let list = in_progress();
    let persisted = temp.persist(&target);
    drop(list);
    persisted.map_err(|e| io(e.error))?;
    Ok(())
}

/// Whether this program may replace the existing regular file `path` (metadata `meta`), as the
/// shell's `>` would write it: refused when the file is read-only for this user (a result kept
/// with `chmod a-w`), or when it lies in a folder with the sticky bit (`/tmp`) and neither the
/// file nor the folder is this user's, where the system refuses the rename after the work.
fn replaceable(path: &Path, meta: &std::fs::Metadata) -> Result<(), ErrorKind> {
    if let Err(e) = OpenOptions::new().write(true).open(path) {
        return Err(if e.kind() == std::io::ErrorKind::PermissionDenied {
            ErrorKind::Mismatch(
                "is read-only for this user: make it writable or choose another output".to_owned(),
            )
        } else {
            ErrorKind::Io(e)
        });
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let folder = folder_of(path);
        let Ok(folder_meta) = std::fs::metadata(folder) else {
            return Ok(());
        };
        const STICKY: u32 = 0o1000;
        if folder_meta.mode() & STICKY != 0 {
            // This user's id, as the system gives it to a file it makes.
            let user = tempfile::tempfile_in(folder)
                .and_then(|f| f.metadata())
                .map(|m| m.uid());
            if let Ok(user) = user
                && user != 0
                && user != meta.uid()
                && user != folder_meta.uid()
            {
                return Err(ErrorKind::Mismatch(format!(
                    "belongs to another user in {}, whose sticky bit lets only the file's owner \
                     replace it: choose another output",
                    folder.display()
                )));
            }
        }
    }
    Ok(())
}

/// Checks, before any work, that a write to `path` ([`write_file`]) will not be refused for
/// its existing target: not read-only for this user, not another user's in a sticky folder.
/// Nothing to check for a target that does not exist yet, a device or a descriptor.
pub fn check_replaceable(path: &Path) -> Result<(), IoError> {
    if descriptor(path).is_some() {
        return Ok(());
    }
    let Some(target) = write_target(path) else {
        return Ok(());
    };
    match std::fs::metadata(&target) {
        Ok(meta) if meta.is_file() => replaceable(&target, &meta).map_err(|k| k.in_file(path)),
        _ => Ok(()),
    }
}

/// The longest file name the usual file systems take, in bytes (Linux's `NAME_MAX`; 255 UTF-16
/// units on Windows, never fewer than bytes).
const MAX_NAME_BYTES: usize = 255;
/// The random characters of a temporary name, and its end.
const TEMPORARY_RANDOM: usize = 6;
const TEMPORARY_SUFFIX: &str = ".partial";

/// The start of a target's temporary name, `.NAME.`: with the random characters and `.partial`
/// it is the target's name 16 bytes longer, so the name of a target within 16 bytes of the
/// limit is cut to fit (a temporary name still hidden, and unique by its random characters).
fn temporary_prefix(name: &std::ffi::OsStr) -> std::ffi::OsString {
    let room = MAX_NAME_BYTES - 2 - TEMPORARY_RANDOM - TEMPORARY_SUFFIX.len();
    #[cfg(unix)]
    {
        use std::os::unix::ffi::{OsStrExt, OsStringExt};
        let bytes = name.as_bytes();
        let kept = &bytes[..bytes.len().min(room)];
        std::ffi::OsString::from_vec([b".", kept, b"."].concat())
    }
    #[cfg(not(unix))]
    {
        let name = name.to_string_lossy();
        let mut end = name.len().min(room);
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        std::ffi::OsString::from(format!(".{}.", &name[..end]))
    }
}

/// The links followed at most, as the system allows (Linux's `MAXSYMLINKS`).
const MAX_LINKS: usize = 40;

/// Where the symbolic link `link` leads, one step: a relative target from the link's own folder.
fn link_target(link: &Path) -> Option<PathBuf> {
    let target = std::fs::read_link(link).ok()?;
    Some(match link.parent() {
        Some(folder) if target.is_relative() => folder.join(target),
        _ => target,
    })
}

/// The folder of `path`, `.` for a bare name.
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// An open file descriptor that a path leads to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Descriptor {
    /// This program's standard output (`/dev/stdout`, `/proc/self/fd/1`).
    Stdout,
    /// This program's standard error.
    Stderr,
    /// Another descriptor, of this program or another: the link that names it
    /// (`/proc/PID/fd/N`, `/dev/fd/N`).
    Other(PathBuf),
}

/// The open file descriptor `path` leads to, following symbolic links: a path whose folder is a
/// process's descriptor table (`/proc/PID/fd`, `/proc/PID/task/TID/fd`, `/dev/fd`) and whose
/// name is a number, as `/dev/stdout` (a link to `/proc/self/fd/1`) and `/dev/fd/2` are. Such a
/// link names the file the descriptor has open (on Linux, a regular file as well as a pipe or a
/// terminal), and a write must go through the descriptor: renaming a new file over the one it
/// names would cut the descriptor's file from its name, and lose what the file held (a log
/// redirected with `>>`). `None` for any other path.
#[must_use]
pub fn descriptor(path: &Path) -> Option<Descriptor> {
    let mut current = path.to_path_buf();
    for _ in 0..=MAX_LINKS {
        if let Some((pid, fd)) = descriptor_link(&current) {
            let own = pid.is_none_or(|pid| pid == std::process::id());
            return Some(match fd {
                1 if own => Descriptor::Stdout,
                2 if own => Descriptor::Stderr,
                _ => Descriptor::Other(current),
            });
        }
        let meta = std::fs::symlink_metadata(&current).ok()?;
        if !meta.file_type().is_symlink() {
            return None;
        }
        current = link_target(&current)?;
    }
    None
}

/// The process (`None` for `/dev/fd`: the caller's own) and descriptor number of `path` when its
/// folder is a descriptor table and its name a number.
fn descriptor_link(path: &Path) -> Option<(Option<u32>, u32)> {
    let fd: u32 = path.file_name()?.to_str()?.parse().ok()?;
    let folder = std::fs::canonicalize(folder_of(path)).ok()?;
    if folder == Path::new("/dev/fd") {
        return Some((None, fd));
    }
    let parts: Vec<&str> = folder
        .components()
        .skip(1)
        .map(|c| c.as_os_str().to_str())
        .collect::<Option<_>>()?;
    let pid = match parts[..] {
        ["proc", pid, "fd"] | ["proc", pid, "task", _, "fd"] => pid.parse().ok()?,
        _ => return None,
    };
    Some((Some(pid), fd))
}

/// The file a write to `path` makes or replaces: a symbolic link's target, followed through
/// every link even where the last one dangles (a link to a file not made yet: the file is made
/// there, and the link then leads to it), else `path` itself. `None` for links that lead back to
/// themselves.
#[must_use]
pub fn write_target(path: &Path) -> Option<PathBuf> {
    let mut current = path.to_path_buf();
    for _ in 0..=MAX_LINKS {
        match std::fs::symlink_metadata(&current) {
            Ok(meta) if meta.file_type().is_symlink() => {
                if let Ok(canonical) = std::fs::canonicalize(&current) {
                    return Some(canonical);
                }
                // Dangling: follow it by hand.
                current = link_target(&current)?;
            }
            _ => return Some(current),
        }
    }
    None
}

/// Whether two paths name one file, as a tool compares its outputs with its inputs before any
/// work: the same file by [`write_target`]'s rule (a symbolic link names the file it leads to,
/// dangling or not, and a file not made yet is its folder's canonical form joined with its
/// name), or on Unix the same device and inode (hard links, which the rename of a write would
/// otherwise split silently). A path whose folder does not exist names no file, so it is no
/// other path's file.
#[must_use]
pub fn same_file(a: &Path, b: &Path) -> bool {
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

/// The first of `pieces` (the files of a parallel mesh's pieces, inputs too) that is the file
/// `output` ([`same_file`]): its index and path.
#[must_use]
pub fn piece_file<'a>(output: &Path, pieces: &'a [PathBuf]) -> Option<(usize, &'a Path)> {
    pieces
        .iter()
        .enumerate()
        .find(|(_, file)| same_file(output, file))
        .map(|(piece, file)| (piece, file.as_path()))
}

/// The file a path names, for comparing: its canonical form when it exists, else the canonical
/// form of the file a write there would make ([`write_target`]), else that file's folder's
/// canonical form joined with its name (the folder must exist). A symbolic link names the file
/// it leads to, dangling or not, so a dangling `known.csv -> mesh.vtu` beside a `mesh.vtu` of
/// the same run is that file.
fn identity(path: &Path) -> Option<PathBuf> {
    if let Ok(canonical) = std::fs::canonicalize(path) {
        return Some(canonical);
    }
    let path = write_target(path)?;
    if let Ok(canonical) = std::fs::canonicalize(&path) {
        return Some(canonical);
    }
    let name = path.file_name()?;
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(folder).ok()?.join(name))
}

/// The writer's result, flushed; where the writer failed because the file did (a full disk),
/// that I/O error rather than the writer's rendering of it.
fn finish<W: Write>(result: Result<(), ErrorKind>, mut out: Recorder<W>) -> Result<(), ErrorKind> {
    let flushed = out.flush();
    match (result, out.error.take()) {
        (Err(_), Some(io)) => Err(ErrorKind::Io(io)),
        (Err(e), None) => Err(e),
        (Ok(()), Some(io)) => Err(ErrorKind::Io(io)),
        (Ok(()), None) => flushed.map_err(ErrorKind::Io),
    }
}

/// A writer that keeps the first I/O error it met: some writers (vtkio's XML serializer) report a
/// full disk as their own "deserialization error", and the user must read "no space left".
struct Recorder<W: Write> {
    inner: W,
    error: Option<std::io::Error>,
}

impl<W: Write> Recorder<W> {
    fn new(inner: W) -> Self {
        Self { inner, error: None }
    }

    fn keep<T>(&mut self, result: std::io::Result<T>) -> std::io::Result<T> {
        result.map_err(|e| {
            let copy = std::io::Error::new(e.kind(), e.to_string());
            self.error.get_or_insert(e);
            copy
        })
    }
}

impl<W: Write> Write for Recorder<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let result = self.inner.write(buf);
        self.keep(result)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        let result = self.inner.flush();
        self.keep(result)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fail_halfway(out: &mut dyn Write) -> Result<(), ErrorKind> {
        out.write_all(b"point,cell\n0,1\n")?;
        Err(ErrorKind::Mismatch("the writer gave up halfway".to_owned()))
    }

    /// A write that fails halfway leaves the old file as it was and no temporary file behind.
    #[cfg(target_os = "linux")]
    #[test]
    fn descriptors_are_told_from_files() {
        let own = std::process::id();
        assert_eq!(
            descriptor(Path::new("/dev/stdout")),
            Some(Descriptor::Stdout)
        );
        assert_eq!(
            descriptor(Path::new("/dev/stderr")),
            Some(Descriptor::Stderr)
        );
        assert_eq!(descriptor(Path::new("/dev/fd/1")), Some(Descriptor::Stdout));
        let path = format!("/proc/{own}/fd/2");
        assert_eq!(descriptor(Path::new(&path)), Some(Descriptor::Stderr));
        let path = PathBuf::from("/proc/self/fd/7");
        assert_eq!(descriptor(&path), Some(Descriptor::Other(path.clone())));
        // Another process's standard output is not ours.
        let path = PathBuf::from("/proc/1/fd/1");
        assert_eq!(descriptor(&path), Some(Descriptor::Other(path.clone())));
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("1");
        std::fs::write(&file, "x").unwrap();
        assert_eq!(descriptor(&file), None);
        // A link to a descriptor is one too; a link to a file is not.
        let link = dir.path().join("out");
        std::os::unix::fs::symlink("/dev/stdout", &link).unwrap();
        assert_eq!(descriptor(&link), Some(Descriptor::Stdout));
        let link = dir.path().join("plain");
        std::os::unix::fs::symlink(&file, &link).unwrap();
        assert_eq!(descriptor(&link), None);
        assert_eq!(descriptor(Path::new("/dev/null")), None);
    }

    #[test]
    fn failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("results.csv");
        std::fs::write(&path, "old content\n").unwrap();
        let error = write_file(&path, fail_halfway).unwrap_err();
        assert!(error.to_string().contains("halfway"), "{error}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old content\n");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("results.csv")]);
    }

    /// Until the write completes the target holds its old content: the new one goes elsewhere.
    #[test]
    fn target_is_untouched_until_the_write_completes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("results.csv");
        std::fs::write(&path, "old\n").unwrap();
        write_file(&path, |out| {
            out.write_all(b"new\n")?;
            out.flush()?;
            assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
            Ok(())
        })
        .unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new\n");
    }

    /// A symbolic link is written through: the link stays, its target gets the content.
    #[cfg(unix)]
    #[test]
    fn symlink_is_written_through() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.csv");
        let link = dir.path().join("link.csv");
        std::fs::write(&real, "old\n").unwrap();
        std::os::unix::fs::symlink(&real, &link).unwrap();
        write_file(&link, |out| Ok(out.write_all(b"new\n")?)).unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read_to_string(&real).unwrap(), "new\n");
    }

    /// A name of 240 to 255 bytes is a valid file name, but `.NAME.XXXXXX.partial` was 16 bytes
    /// longer: the write failed after the work with "File name too long (os error 36)".
    #[test]
    fn names_near_the_length_limit_are_written() {
        let dir = tempfile::tempdir().unwrap();
        for length in [239, 240, 250, 255] {
            let name = format!("{}.csv", "r".repeat(length - 4));
            let path = dir.path().join(&name);
            write_file(&path, |out| Ok(out.write_all(b"x\n")?))
                .unwrap_or_else(|e| panic!("{length} bytes: {e}"));
            assert_eq!(std::fs::read_to_string(&path).unwrap(), "x\n");
        }
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().ends_with(".partial"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }

    /// A symbolic link to a file not made yet was replaced by a regular file, its target never
    /// made: the link is written through, the file made at its target, in the target's folder.
    #[cfg(unix)]
    #[test]
    fn dangling_symlink_is_written_through_to_its_target() {
        let dir = tempfile::tempdir().unwrap();
        let elsewhere = dir.path().join("elsewhere");
        std::fs::create_dir(&elsewhere).unwrap();
        let link = dir.path().join("link.csv");
        // Relative to the link's folder, through a second dangling link.
        std::os::unix::fs::symlink("second.csv", &link).unwrap();
        std::os::unix::fs::symlink("elsewhere/made.csv", dir.path().join("second.csv")).unwrap();
        write_file(&link, |out| Ok(out.write_all(b"new\n")?)).unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(
            std::fs::read_to_string(elsewhere.join("made.csv")).unwrap(),
            "new\n"
        );
        // Links in a loop are an error, not a file made in their place.
        let a = dir.path().join("a.csv");
        std::os::unix::fs::symlink("b.csv", &a).unwrap();
        std::os::unix::fs::symlink("a.csv", dir.path().join("b.csv")).unwrap();
        let error = write_file(&a, |out| Ok(out.write_all(b"x\n")?)).unwrap_err();
        assert!(error.to_string().contains("symbolic links"), "{error}");
        assert!(
            std::fs::symlink_metadata(&a)
                .unwrap()
                .file_type()
                .is_symlink()
        );
    }

    /// Links of every kind name the file they lead to; a file not made yet is told from its
    /// folder and name; different files, or a folder that does not exist, are not the same.
    #[cfg(unix)]
    #[test]
    fn same_file_sees_through_links() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = dir.path().join("mesh.vtu");
        std::fs::write(&mesh, "mesh").unwrap();
        let other = dir.path().join("other.vtu");
        std::fs::write(&other, "other").unwrap();
        assert!(same_file(&mesh, &mesh));
        assert!(!same_file(&mesh, &other));
        // A hard link: another name, the same inode.
        let hard = dir.path().join("hard.vtu");
        std::fs::hard_link(&mesh, &hard).unwrap();
        assert!(same_file(&hard, &mesh));
        // A symbolic link, and one that dangles towards a file a write would make.
        let soft = dir.path().join("soft.vtu");
        std::os::unix::fs::symlink("mesh.vtu", &soft).unwrap();
        assert!(same_file(&soft, &mesh));
        let dangling = dir.path().join("dangling.csv");
        std::os::unix::fs::symlink("made.csv", &dangling).unwrap();
        assert!(same_file(&dangling, &dir.path().join("made.csv")));
        assert!(!same_file(&dangling, &mesh));
        // Not made yet, through a `..`: the folder's canonical form joined with the name.
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let around = dir.path().join("sub").join("..").join("new.csv");
        assert!(same_file(&around, &dir.path().join("new.csv")));
        assert!(!same_file(
            &dir.path().join("missing").join("mesh.vtu"),
            &mesh
        ));
        // The pieces of a parallel mesh: the first that is the output, with its index.
        let pieces = [other.clone(), hard.clone(), mesh.clone()];
        assert_eq!(piece_file(&soft, &pieces), Some((1, hard.as_path())));
        assert_eq!(piece_file(&dangling, &pieces), None);
    }

    /// A full device is reported as such, even through a writer that renders I/O errors its own way.
    #[cfg(target_os = "linux")]
    #[test]
    fn full_device_is_an_io_error_named_as_such() {
        let error = write_file("/dev/full", |out| {
            let big = vec![b'x'; 1 << 20];
            out.write_all(&big)
                .map_err(|_| ErrorKind::Vtk("Deserialization error".to_owned()))
        })
        .unwrap_err();
        let message = error.to_string();
        assert!(message.contains("No space left"), "{message}");
        assert!(matches!(error.kind(), ErrorKind::Io(_)));
    }

    /// New files get the usual permissions, not the temporary file's 0600.
    #[cfg(unix)]
    #[test]
    fn new_files_get_the_usual_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let made = dir.path().join("made.csv");
        std::fs::write(&made, "x\n").unwrap();
        let ours = dir.path().join("ours.csv");
        write_file(&ours, |out| Ok(out.write_all(b"x\n")?)).unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&ours), mode(&made));
    }
}
