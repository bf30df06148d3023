//! Reading an input file whole, within a size limit, refusing at once what cannot be the format.
//!
//! `/dev/zero` given as a mesh or a points file used to be read until memory ran out. Inputs are now
//! read in chunks up to [`max_input_bytes`] (4 GiB unless `CGCONTACT_MAX_INPUT_BYTES` says
//! otherwise), and the first chunk is checked to look like the expected format, so that a device or
//! a binary file is refused after 64 KiB, not after gigabytes. [`read_text`] reads any other text
//! input (a benchmark's log, say) within its own limit and with its own wording, refusing a NUL
//! byte anywhere in it.

use std::io::Read;
use std::path::Path;

use crate::{ErrorKind, IoError};

/// The environment variable that overrides the input size limit (in bytes).
pub const MAX_INPUT_BYTES_VAR: &str = "CGCONTACT_MAX_INPUT_BYTES";

/// The default input size limit: 4 GiB.
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 4 << 30;

/// Bytes read before the format is checked.
const SNIFF_BYTES: u64 = 64 << 10;

/// The input size limit: `CGCONTACT_MAX_INPUT_BYTES` when set to a number of bytes, else
/// [`DEFAULT_MAX_INPUT_BYTES`].
#[must_use]
pub fn max_input_bytes() -> u64 {
    std::env::var(MAX_INPUT_BYTES_VAR)
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(DEFAULT_MAX_INPUT_BYTES)
}

/// What an input file must look like from its first bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Expect {
    /// A VTK file: `# vtk` or `<` after optional whitespace and a byte order mark.
    Vtk,
    /// CSV text: no NUL byte.
    Text,
}

/// What a text file read by [`read_text`] may hold and what its error messages call it.
///
/// ```
/// use cgcontact_io::{TextInput, read_text};
///
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("run.log");
/// let log = TextInput {
///     max_bytes: 1 << 20,
///     what: "a log of run.sh",
///     over_limit: "not a log of run.sh (a few KB)",
/// };
/// std::fs::write(&path, "# started\nrate=5\n")?;
/// assert_eq!(read_text(&path, &log)?, b"# started\nrate=5\n");
///
/// std::fs::write(&path, b"rate=5\n\0")?;
/// let message = read_text(&path, &log).unwrap_err().to_string();
/// assert!(message.ends_with("binary data (a NUL byte at byte 7), not a log of run.sh"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextInput<'a> {
    /// The most bytes read: a larger file is refused before it is read, a stream (a device, a
    /// pipe) once it passes the limit.
    pub max_bytes: u64,
    /// What the file should be, ending the message that refuses binary data: `binary data (a NUL
    /// byte at byte 6), not {what}`.
    pub what: &'a str,
    /// Ending the message that refuses a file over the limit, `more than N bytes (M read or
    /// reported), {over_limit}`: why such a file cannot be the one expected, or how to read it
    /// anyway.
    pub over_limit: &'a str,
}

/// Read the text file at `path` whole, within `input.max_bytes`, refusing binary data at once.
///
/// The file is read in chunks of 64 KiB, each checked for a NUL byte before the next is read, so
/// that `/dev/zero` or a binary file is refused after its first chunk and a text file holds no NUL
/// byte anywhere; a file that starts with a UTF-16 byte order mark is refused as such. The bytes
/// are not checked to be UTF-8: the caller says what else its text must be.
///
/// # Errors
///
/// [`IoError`] naming `path` when it cannot be opened or read, is a folder, holds more than
/// `input.max_bytes` bytes, or is UTF-16 or binary.
pub fn read_text(path: impl AsRef<Path>, input: &TextInput<'_>) -> Result<Vec<u8>, IoError> {
    let path = path.as_ref();
    read_checked(path, input.max_bytes, input.over_limit, |offset, chunk| {
        if offset == 0 {
            check_not_utf16(chunk)?;
        }
        check_no_nul(chunk, offset, input.what)
    })
}

/// Read `path` whole, within [`max_input_bytes`], checking its first bytes against `expect`.
pub(crate) fn read_input(path: &Path, expect: Expect) -> Result<Vec<u8>, IoError> {
    read_within(path, expect, max_input_bytes())
}

/// [`read_input`] with the limit given.
fn read_within(path: &Path, expect: Expect, limit: u64) -> Result<Vec<u8>, IoError> {
    let over_limit = format!(
        "the input size limit; set {MAX_INPUT_BYTES_VAR} to a larger number of bytes to read it"
    );
    read_checked(path, limit, &over_limit, |offset, chunk| {
        // Only the start: a binary VTK file holds NUL bytes after its header.
        if offset == 0 {
            check_start(chunk, expect)
        } else {
            Ok(())
        }
    })
}

/// Read `path` whole, at most `limit` bytes, in chunks of [`SNIFF_BYTES`], each given to `check`
/// with its offset before the next is read; `over_limit` ends the message that refuses a file
/// over the limit.
fn read_checked(
    path: &Path,
    limit: u64,
    over_limit: &str,
    mut check: impl FnMut(u64, &[u8]) -> Result<(), ErrorKind>,
) -> Result<Vec<u8>, IoError> {
    let io = |e: std::io::Error| ErrorKind::Io(e).in_file(path);
    let too_big = |size: u64| {
        ErrorKind::Format(format!(
            "more than {limit} bytes ({size} read or reported), {over_limit}"
        ))
        .in_file(path)
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if meta.is_dir() {
        // The system's kind, so that callers can tell it (Python raises IsADirectoryError).
        let folder =
            std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a folder, not a file");
        return Err(io(folder));
    }
    if meta.is_file() && meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let mut bytes = Vec::new();
    let mut reader = file.take(limit.saturating_add(1));
    loop {
        let start = bytes.len();
        let read = (&mut reader)
            .take(SNIFF_BYTES)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        if read == 0 {
            break;
        }
        check(start as u64, &bytes[start..]).map_err(|e| e.in_file(path))?;
    }
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

/// Refuse, from its first bytes, a file that cannot be of the expected format.
fn check_start(bytes: &[u8], expect: Expect) -> Result<(), ErrorKind> {
    check_not_utf16(bytes)?;
    match expect {
        Expect::Text => check_no_nul(bytes, 0, "CSV text"),
        Expect::Vtk => {
            let start = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
            let start = &start[start
                .iter()
                .position(|b| !b.is_ascii_whitespace())
                .unwrap_or(start.len())..];
            let legacy = start.len() >= 5 && start[..5].eq_ignore_ascii_case(b"# vtk");
            // Too short to tell: let the parser say what is wrong.
            let short = start.len() < 5 && b"# vtk"[..start.len()].eq_ignore_ascii_case(start);
            if legacy || start.first() == Some(&b'<') || short {
                Ok(())
            } else {
                Err(ErrorKind::Format(format!(
                    "neither a legacy VTK file (`# vtk DataFile ...`) nor an XML VTK file (`<VTKFile ...>`): it starts with {}",
                    crate::excerpt(start, 12)
                )))
            }
        }
    }
}

/// Refuse text saved as "Unicode" by some editors (Excel's "Unicode text"): named, not called
/// binary.
fn check_not_utf16(start: &[u8]) -> Result<(), ErrorKind> {
    if start.starts_with(b"\xFF\xFE") || start.starts_with(b"\xFE\xFF") {
        return Err(ErrorKind::Format(
            "UTF-16 text (it starts with a UTF-16 byte order mark): save it as UTF-8 or ASCII"
                .to_owned(),
        ));
    }
    Ok(())
}

/// Refuse `chunk`, found at byte `offset` of a file that should be `what`, if it holds a NUL byte.
fn check_no_nul(chunk: &[u8], offset: u64, what: &str) -> Result<(), ErrorKind> {
    match chunk.iter().position(|&b| b == 0) {
        Some(at) => Err(ErrorKind::Format(format!(
            "binary data (a NUL byte at byte {}), not {what}",
            offset + at as u64
        ))),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `/dev/zero` is refused from its first chunk, as a mesh and as points.
    #[cfg(target_os = "linux")]
    #[test]
    fn dev_zero_is_refused_at_once() {
        for expect in [Expect::Vtk, Expect::Text] {
            let error = read_input(Path::new("/dev/zero"), expect).unwrap_err();
            let message = error.to_string();
            assert!(message.contains("/dev/zero"), "{message}");
            assert!(
                message.contains("NUL byte at byte 0") || message.contains("neither a legacy"),
                "{message}"
            );
        }
    }

    /// A file over the limit is refused before it is read; a stream, once it passes the limit.
    #[test]
    fn inputs_over_the_limit_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("points.csv");
        std::fs::write(&path, "x,y,z\n1,2,3\n").unwrap();
        assert!(read_within(&path, Expect::Text, 12).is_ok());
        let message = read_within(&path, Expect::Text, 11)
            .unwrap_err()
            .to_string();
        assert!(message.contains(MAX_INPUT_BYTES_VAR), "{message}");
        #[cfg(target_os = "linux")]
        {
            // A device reports no size: the limit applies to what is read. Random bytes are
            // refused by their start, or, when the start happens to pass (a leading '#', '<' or
            // blank: a few draws in a hundred), by the limit.
            let message = read_within(Path::new("/dev/urandom"), Expect::Vtk, 1 << 20)
                .unwrap_err()
                .to_string();
            assert!(
                message.contains("neither a legacy") || message.contains(MAX_INPUT_BYTES_VAR),
                "{message}"
            );
        }
    }

    /// `read_text` refuses a NUL byte in any chunk, naming its offset, and words both refusals
    /// as told; a CSV file is checked for NUL bytes in its first chunk only.
    #[test]
    fn text_is_refused_in_its_own_words() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.log");
        let log = TextInput {
            max_bytes: 1 << 20,
            what: "a log",
            over_limit: "not a log (a few KB)",
        };
        let mut late_nul = vec![b'#'; 3 * SNIFF_BYTES as usize];
        late_nul[2 * SNIFF_BYTES as usize + 5] = 0;
        std::fs::write(&path, &late_nul).unwrap();
        let message = read_text(&path, &log).unwrap_err().to_string();
        let at = 2 * SNIFF_BYTES + 5;
        assert!(
            message.ends_with(&format!("binary data (a NUL byte at byte {at}), not a log")),
            "{message}"
        );
        assert!(read_within(&path, Expect::Text, 1 << 20).is_ok());
        std::fs::write(&path, "# run\n").unwrap();
        assert_eq!(read_text(&path, &log).unwrap(), b"# run\n");
        let small = TextInput {
            max_bytes: 5,
            ..log
        };
        let message = read_text(&path, &small).unwrap_err().to_string();
        assert!(
            message.ends_with("more than 5 bytes (6 read or reported), not a log (a few KB)"),
            "{message}"
        );
        std::fs::write(&path, b"\xFF\xFE#\0").unwrap();
        let message = read_text(&path, &log).unwrap_err().to_string();
        assert!(message.contains("UTF-16"), "{message}");
    }

    #[test]
    fn the_start_of_each_format_passes() {
        for (bytes, expect) in [
            (&b"\xEF\xBB\xBF  # vtk DataFile"[..], Expect::Vtk),
            (b"\n<VTKFile", Expect::Vtk),
            (b"", Expect::Vtk),
            (b"# v", Expect::Vtk),
            (b"x,y,z\n1,2,3\n", Expect::Text),
        ] {
            check_start(bytes, expect).unwrap();
        }
        assert!(check_start(b"PK\x03\x04", Expect::Vtk).is_err());
    }
}
