//! `abandon_writes`, what an interrupted program calls before it exits. It locks the list of
//! writes in progress for the rest of the process, so it has a test binary of its own.

use std::io::Write;
use std::sync::mpsc;
use std::time::Duration;

use cgcontact_io::{ErrorKind, abandon_writes, write_file};

fn names(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A write caught halfway loses its temporary file and never replaces its target; a write begun
/// afterwards makes no temporary file and never reaches its target either.
#[test]
fn abandoned_writes_leave_targets_as_they_were_and_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("results.csv");
    std::fs::write(&target, "old\n").unwrap();
    let (started, halfway) = mpsc::channel();
    let (release, wait) = mpsc::channel::<()>();
    let (done, finished) = mpsc::channel();
    let path = target.clone();
    std::thread::spawn(move || {
        let result = write_file(&path, |out: &mut dyn Write| {
            out.write_all(b"new, half written\n")?;
            out.flush()?;
            started.send(()).unwrap();
            wait.recv()
                .map_err(|e| ErrorKind::Mismatch(e.to_string()))?;
            out.write_all(b"the rest\n")?;
            Ok(())
        });
        done.send(result.is_ok()).unwrap();
    });
    halfway.recv().unwrap();
    let partial = names(dir.path());
    assert_eq!(partial.len(), 2, "{partial:?}");
    assert!(
        partial.iter().any(|n| n.ends_with(".partial")),
        "{partial:?}"
    );

    assert_eq!(abandon_writes(), 1);
    assert_eq!(names(dir.path()), ["results.csv"]);

    // The writer completes its content; its rename waits for ever, as the process would exit.
    release.send(()).unwrap();
    assert!(finished.recv_timeout(Duration::from_millis(300)).is_err());
    let later = dir.path().join("later.csv");
    let path = later.clone();
    std::thread::spawn(move || write_file(&path, |out| Ok(out.write_all(b"later\n")?)));
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "old\n");
    assert_eq!(names(dir.path()), ["results.csv"]);
    assert!(!later.exists());
}
