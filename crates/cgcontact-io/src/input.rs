//! Reading an input file whole, within a size limit, refusing at once what cannot be the format.
//!
//! `/dev/zero` given as a mesh or a points file used to be read until memory ran out. Inputs are now
//! read in chunks up to [`max_input_bytes`] (4 GiB unless `CGCONTACT_MAX_INPUT_BYTES` says
//! otherwise), and the first chunk is checked to look like the expected format, so that a device or
//! a binary file is refused after 64 KiB, not after gigabytes.

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

/// Read `path` whole, within [`max_input_bytes`], checking its first bytes against `expect`.
pub(crate) fn read_input(path: &Path, expect: Expect) -> Result<Vec<u8>, IoError> {
    read_within(path, expect, max_input_bytes())
}

/// [`read_input`] with the limit given.
fn read_within(path: &Path, expect: Expect, limit: u64) -> Result<Vec<u8>, IoError> {
    let io = |e: std::io::Error| ErrorKind::Io(e).in_file(path);
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if meta.is_dir() {
        return Err(ErrorKind::Format("is a folder, not a file".to_owned()).in_file(path));
    }
    if meta.is_file() && meta.len() > limit {
        return Err(too_big(meta.len(), limit).in_file(path));
    }
    let mut bytes = Vec::new();
    let mut reader = file.take(limit.saturating_add(1));
    (&mut reader)
        .take(SNIFF_BYTES)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    check_start(&bytes, expect).map_err(|e| e.in_file(path))?;
    reader.read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64, limit).in_file(path));
    }
    Ok(bytes)
}

fn too_big(size: u64, limit: u64) -> ErrorKind {
    ErrorKind::Format(format!(
        "more than {limit} bytes ({size} read or reported), the input size limit; set {MAX_INPUT_BYTES_VAR} to a larger number of bytes to read it"
    ))
}

/// Refuse, from its first bytes, a file that cannot be of the expected format.
fn check_start(bytes: &[u8], expect: Expect) -> Result<(), ErrorKind> {
    // Saved as "Unicode" by some editors (Excel's "Unicode text"): named, not called binary.
    if bytes.starts_with(b"\xFF\xFE") || bytes.starts_with(b"\xFE\xFF") {
        return Err(ErrorKind::Format(
            "UTF-16 text (it starts with a UTF-16 byte order mark): save it as UTF-8 or ASCII"
                .to_owned(),
        ));
    }
    match expect {
        Expect::Text => match bytes.iter().position(|&b| b == 0) {
            Some(at) => Err(ErrorKind::Format(format!(
                "binary data (a NUL byte at byte {at}), not CSV text"
            ))),
            None => Ok(()),
        },
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
