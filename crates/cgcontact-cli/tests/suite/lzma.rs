//! `cgcontact locate` on meshes VTK 9.7.2 wrote with its LZMA compressor (fixtures/vtk-written and
//! fixtures/vtk-written-adaptive, made by their make.py): the same answers, byte for byte, as on
//! another flavour of the same scene; and on hostile variants of them (a huge block header, a
//! corrupted or cut .xz stream, a wrong check, data that is not .xz), exit code 2 with one line
//! naming the file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn fixtures(folder: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(folder)
}

/// The first three columns of a CSV file's rows after `skip` lines, as a points file.
fn points_from(csv: &Path, skip: usize, out: &Path) {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut points = String::from("x,y,z\n");
    for line in text.lines().skip(skip) {
        let x: Vec<&str> = line.split(',').take(3).collect();
        points += &format!("{}\n", x.join(","));
    }
    std::fs::write(out, points).unwrap();
}

fn locate(mesh: &Path, points: &Path, out: &Path, flags: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .arg("locate")
        .arg("--mesh")
        .arg(mesh)
        .arg("--points")
        .arg(points)
        .arg("--out")
        .arg(out)
        .args(flags)
        .output()
        .unwrap()
}

#[test]
fn locate_answers_on_lzma_files_as_on_the_other_flavours() {
    let dir = tempfile::tempdir().unwrap();
    let uniform = fixtures("vtk-written");
    let adaptive = fixtures("vtk-written-adaptive");
    let known = dir.path().join("known.csv");
    points_from(&uniform.join("known.csv"), 1, &known);
    let sheared_1e5 = dir.path().join("sheared-1e5.csv");
    points_from(&adaptive.join("sheared-1e5.expected.csv"), 2, &sheared_1e5);
    let sheared_m1e7 = dir.path().join("sheared-m1e7.csv");
    points_from(
        &adaptive.join("sheared-m1e7.expected.csv"),
        2,
        &sheared_m1e7,
    );
    // (reference mesh, LZMA meshes, points, flags)
    let cases: [(PathBuf, Vec<PathBuf>, &Path, &[&str]); 3] = [
        (
            uniform.join("xml-appended-raw.vtu"),
            [
                "xml-binary-lzma.vtu",
                "xml-binary-lzma-blocks.vtu",
                "xml-appended-raw-lzma-uint64.vtu",
                "xml-appended-base64-lzma.vtu",
            ]
            .map(|f| uniform.join(f))
            .to_vec(),
            &known,
            &[],
        ),
        (
            adaptive.join("sheared-1e5.legacy-binary.vtk"),
            vec![
                adaptive.join("sheared-1e5.appended-lzma.vtu"),
                adaptive.join("sheared-1e5.binary-lzma-uint64.vtu"),
            ],
            &sheared_1e5,
            &["--all-owners", "--strict"],
        ),
        (
            adaptive.join("sheared-m1e7.binary-zlib.vtu"),
            vec![adaptive.join("sheared-m1e7.appended-base64-lzma.vtu")],
            &sheared_m1e7,
            &["--all-owners", "--strict"],
        ),
    ];
    for (reference, meshes, points, flags) in cases {
        let want = dir.path().join("want.csv");
        let run = locate(&reference, points, &want, flags);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let want = std::fs::read(&want).unwrap();
        assert!(want.len() > 1000);
        for mesh in meshes {
            let got = dir.path().join("got.csv");
            let run = locate(&mesh, points, &got, flags);
            assert!(
                run.status.success() && run.stderr.is_empty(),
                "{}: {}",
                mesh.display(),
                String::from_utf8_lossy(&run.stderr)
            );
            assert!(
                std::fs::read(&got).unwrap() == want,
                "{} answers otherwise than {}",
                mesh.display(),
                reference.display()
            );
        }
    }
}

#[test]
fn hostile_lzma_files_exit_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "x,y,z\n1000.3,-1999.9,3000.1\n").unwrap();
    let raw =
        std::fs::read(fixtures("vtk-written").join("xml-appended-raw-lzma-uint64.vtu")).unwrap();
    let find = |needle: &[u8]| raw.windows(needle.len()).position(|w| w == needle).unwrap();
    // The first array's 64-bit block header `[1, block size, last size, compressed size]` and
    // its .xz stream.
    let header = find(b"<AppendedData");
    let header = header + raw[header..].iter().position(|&b| b == b'_').unwrap() + 1;
    let held = u64::from_le_bytes(raw[header + 24..header + 32].try_into().unwrap()) as usize;
    let stream = header + 32..header + 32 + held;
    let edit = |at: usize, bytes: &[u8]| {
        let mut out = raw.clone();
        out[at..at + bytes.len()].copy_from_slice(bytes);
        out
    };
    let mut corrupt = raw.clone();
    corrupt[stream.start + held / 2] ^= 0x5A;
    let mut check = raw.clone();
    // The block's CRC32 ends 4 bytes before the index, which the footer's backward size places.
    let backward = u32::from_le_bytes(raw[stream.end - 8..stream.end - 4].try_into().unwrap());
    check[stream.end - 12 - 4 * (backward as usize + 1) - 4] ^= 0x01;
    let variants = [
        // Block size and last block size 2^50 (the one block is the last).
        (
            "huge-header",
            edit(header + 8, &[(1u64 << 50).to_le_bytes(); 2].concat()),
        ),
        ("corrupt-stream", corrupt),
        ("wrong-check", check),
        ("not-xz", edit(stream.start, b"PK\x03\x04\x00\x00")),
        ("truncated", raw[..stream.start + held / 2].to_vec()),
    ];
    for (name, bytes) in variants {
        let mesh = dir.path().join(format!("{name}.vtu"));
        std::fs::write(&mesh, bytes).unwrap();
        let run = locate(&mesh, &points, &dir.path().join("out.csv"), &[]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{name}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{name}: {stderr}");
        assert!(
            stderr.contains(&mesh.display().to_string()) && stderr.contains("LZMA-compressed"),
            "{name}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
    }
}
