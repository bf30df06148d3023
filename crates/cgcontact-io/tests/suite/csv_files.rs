//! CSV points and results: good files, every bad row named by its line, round trips.

use cgcontact::glam::DVec3;
use cgcontact::{Body, Lattice, LatticeLocator, Locator, Settings};
use cgcontact_io::{
    CellMap, ErrorKind, Num, RESULTS_HEADER, parse_points, read_points, read_results, write_points,
    write_results,
};

fn points(text: &str) -> Result<Vec<DVec3>, ErrorKind> {
    parse_points(text.as_bytes())
}

fn line_of(text: &str) -> u64 {
    match points(text) {
        Err(ErrorKind::Csv { line, .. }) => line,
        other => panic!("expected a CSV error for {text:?}, got {other:?}"),
    }
}

#[test]
fn good_files_with_and_without_header() {
    let expected = vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(-0.5, 1e-300, 4e6)];
    assert_eq!(points("x,y,z\n1,2,3\n-0.5,1e-300,4e6\n").unwrap(), expected);
    assert_eq!(points("1,2,3\n-0.5,1e-300,4e6").unwrap(), expected);
    assert_eq!(
        points("# contact points\n X , Y , Z \n\n 1 , 2 ,3\r\n-0.5,1e-300,4e6\r\n").unwrap(),
        expected
    );
    let odd = points("nan,inf,-inf\n1,2,3\n").unwrap();
    assert!(odd[0].x.is_nan() && odd[0].y == f64::INFINITY && odd[0].z == f64::NEG_INFINITY);
}

/// A header naming x, y and z in another order was skipped and its columns read as x, y, z: a
/// `z,y,x` file had its points mirrored without a word. Each column is now the axis it names;
/// a header that names an axis out of its column without naming all three is an error.
#[test]
fn a_header_naming_the_axes_in_another_order_is_followed() {
    let expected = vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(-0.5, 7.0, 4e6)];
    for (header, rows) in [
        ("z,y,x", "3,2,1\n4e6,7,-0.5\n"),
        ("y,z,x", "2,3,1\n7,4e6,-0.5\n"),
        (" Z , X ,y", "3,1,2\n4e6,-0.5,7\n"),
        ("\"x\",\"z\",\"y\"", "1,3,2\n-0.5,4e6,7\n"),
        // Named in place, or not named: by position.
        ("x,y,depth", "1,2,3\n-0.5,7,4e6\n"),
        ("a,b,c", "1,2,3\n-0.5,7,4e6\n"),
    ] {
        let read = points(&format!("{header}\n{rows}")).unwrap();
        assert_eq!(read, expected, "{header}");
    }
    for header in ["y,x,depth", "x,x,z", "a,x,c", "z,z,z"] {
        let message = message_of(&format!("{header}\n1,2,3\n"));
        assert!(
            message.contains("line 1") && message.contains("out of their columns"),
            "{header}: {message}"
        );
    }
}

/// A quoted name after a space (`"x", "z", "y"`, as a header written by hand or with `", "`
/// between fields comes out) kept its quotes: the CSV reader unquotes a field only when the
/// quote is its first byte. Named by none of x, y and z, such a header was read by position,
/// its points' y and z swapped without a word. So were single-quoted names (`'z','y','x'`).
#[test]
fn a_quoted_header_after_spaces_is_followed_by_name() {
    let expected = vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(-0.5, 7.0, 4e6)];
    for (header, rows) in [
        ("\"x\", \"z\", \"y\"", "1,3,2\n-0.5,4e6,7\n"),
        ("x, \"z\" , \" y \"", "1,3,2\n-0.5,4e6,7\n"),
        ("'z','y','x'", "3,2,1\n4e6,7,-0.5\n"),
        ("\"Z\", \"Y\", \"X\"", "3,2,1\n4e6,7,-0.5\n"),
    ] {
        let read = points(&format!("{header}\n{rows}")).unwrap();
        assert_eq!(read, expected, "{header}");
    }
    // Quoted out of place without naming all three is refused as unquoted names are.
    let message = message_of("x, \"x\", z\n1,2,3\n");
    assert!(message.contains("out of their columns"), "{message}");
}

/// A header naming its axes with units (`x_mm,z_mm,y_mm`) or qualifiers (`pos_x`) named no
/// axis, so it was read by position: y and z swapped without a word. Such names are now the
/// axis they carry; a name carrying two (`x_y`) or none (`max`, `xi`, `depth`) names none.
#[test]
fn axis_names_with_units_or_qualifiers_are_followed() {
    let expected = vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(-0.5, 7.0, 4e6)];
    for header in [
        "x_mm,z_mm,y_mm",
        "X [m], Z [m], Y [m]",
        "\"x (mm)\",\"z (mm)\",\"y (mm)\"",
        "pos_x,pos_z,pos_y",
        "coord.X,coord.Z,coord.Y",
        "x/m,z-m,y:m",
    ] {
        let read = points(&format!("{header}\n1,3,2\n-0.5,4e6,7\n")).unwrap();
        assert_eq!(read, expected, "{header}");
    }
    // Names in their columns, or naming no axis, are read by position as before.
    for header in [
        "x_mm,y_mm,z_mm",
        "max,xi,depth",
        "x_y,b,c",
        "Points:0,Points:1,Points:2",
    ] {
        let read = points(&format!("{header}\n1,2,3\n-0.5,7,4e6\n")).unwrap();
        assert_eq!(read, expected, "{header}");
    }
    // One axis out of its column, the others unnamed: refused, not swapped.
    let message = message_of("y_mm,x_mm,depth\n1,2,3\n");
    assert!(message.contains("out of their columns"), "{message}");
}

/// `1e400` was read as an infinite point (Rust's parser rounds a finite number beyond f64's
/// range to infinity) and answered "not finite", as if the file held `inf`. It is the file's
/// value the program cannot hold: an error naming the line and the field. Spelled infinities
/// are still read, and a number that rounds to a subnormal or zero (`1e-400`) is rounding.
#[test]
fn numbers_beyond_f64_are_refused_not_read_as_infinite() {
    for (row, field) in [
        ("1e400,2,3", 1),
        ("1,-1E+309,3", 2),
        ("1,2,1.7976931348623159e308", 3),
    ] {
        let text = format!("x,y,z\n0,0,0\n{row}\n");
        assert_eq!(line_of(&text), 3, "{row}");
        let message = message_of(&text);
        assert!(
            message.contains(&format!("field {field}")) && message.contains("beyond the range"),
            "{row}: {message}"
        );
    }
    let read = points("x,y,z\n1e-400,-Infinity,+INF\n1.7976931348623157e308,0,0\n").unwrap();
    assert_eq!(read[0].x, 0.0);
    assert!(read[0].y == f64::NEG_INFINITY && read[0].z == f64::INFINITY);
    assert_eq!(read[1].x, f64::MAX);
}

#[test]
fn bad_rows_name_their_line() {
    assert_eq!(line_of("x,y,z\n1,2,3\n1,2\n"), 3);
    assert_eq!(line_of("x,y,z\n1,2,3\n1,2,3,4\n"), 3);
    assert_eq!(line_of("1,2,3\n4,five,6\n"), 2);
    assert_eq!(line_of("1,2,3\n\n# note\n4,5,\n"), 4);
    // A first row with some numbers is data, not a header: its bad field is an error.
    assert_eq!(line_of("1,y,3\n4,5,6\n"), 1);
    assert_eq!(line_of("x,y\n1,2,3\n"), 1);
    assert!(matches!(points(""), Err(ErrorKind::Empty)));
    assert!(matches!(points("x,y,z\n"), Err(ErrorKind::Empty)));
    let raw: &[u8] = b"1,2,3\n\xff,1,2\n";
    assert!(matches!(
        parse_points(raw),
        Err(ErrorKind::Csv { line: 2, .. })
    ));
}

#[test]
fn errors_from_files_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pts.csv");
    std::fs::write(&path, "x,y,z\n0,0,0\n0,zero,0\n").unwrap();
    let message = read_points(&path).unwrap_err().to_string();
    assert!(
        message.contains("pts.csv") && message.contains("line 3") && message.contains("zero"),
        "{message}"
    );
    let missing = read_points(dir.path().join("nope.csv"))
        .unwrap_err()
        .to_string();
    assert!(missing.contains("nope.csv"), "{missing}");
}

#[test]
fn points_and_results_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let pts = vec![
        DVec3::new(0.1, 0.2, 0.3),
        DVec3::new(1.0 / 3.0, 2.0f64.sqrt(), 1e-17),
        DVec3::splat(9.0),
        DVec3::new(f64::NAN, 0.0, 0.0),
    ];
    let path = dir.path().join("points.csv");
    write_points(&path, &pts).unwrap();
    let back = read_points(&path).unwrap();
    assert_eq!(back[..3], pts[..3]);
    assert!(back[3].x.is_nan());

    let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.5), [2, 2, 2]).unwrap();
    let mut body = Body::full(lattice);
    body.update_displacements(|_, x, u| *u = DVec3::new(0.0, 0.0, 0.05 * x.x))
        .unwrap();
    let answers = LatticeLocator::new(&body, Settings::default())
        .unwrap()
        .locate_all(&pts);
    let results = dir.path().join("results.csv");
    let cells = CellMap::ascending(&body);
    write_results(&results, &answers, &cells).unwrap();
    let text = std::fs::read_to_string(&results).unwrap();
    assert!(text.starts_with("point,cell,xi,eta,zeta,"), "{text}");
    assert_eq!(text.lines().next().unwrap(), RESULTS_HEADER.join(","));
    let rows = read_results(&results).unwrap();
    assert_eq!(rows.len(), answers.len());
    for (row, answer) in rows.iter().zip(&answers) {
        match answer {
            Ok(Some(hit)) => {
                assert_eq!(row.cell, cells.input_cell(hit.cell));
                assert_eq!(row.xi, hit.xi, "bitwise");
                assert_eq!(row.iterations, hit.iterations);
                assert_eq!(row.residual, hit.residual);
            }
            _ => {
                assert_eq!(row.cell, None);
                assert!(row.xi.is_nan());
            }
        }
    }
    assert!(rows[0].cell.is_some() && rows[2].cell.is_none() && rows[3].cell.is_none());
    assert_eq!(
        rows.iter().map(|r| r.point).collect::<Vec<_>>(),
        vec![0, 1, 2, 3]
    );

    std::fs::write(
        &results,
        "point,cell,xi,eta,zeta\n0,3,0.5,0,0\n1,-2,0,0,0\n",
    )
    .unwrap();
    let message = read_results(&results).unwrap_err().to_string();
    assert!(
        message.contains("line 3") && message.contains("cell"),
        "{message}"
    );
    std::fs::write(&results, "pt,cell,xi\n").unwrap();
    assert!(
        read_results(&results)
            .unwrap_err()
            .to_string()
            .contains("line 1")
    );
}

fn message_of(text: &str) -> String {
    match points(text) {
        Err(error @ ErrorKind::Csv { .. }) => error.to_string(),
        other => panic!("expected a CSV error for {text:?}, got {other:?}"),
    }
}

/// Points separated by spaces (numpy's `savetxt` default) read "header with 1 fields, expected
/// 3", and a first data row separated by `;` was called a header. Now the separator is named,
/// and the line is not called a header.
#[test]
fn rows_in_another_separator_name_it() {
    for (text, separator, line) in [
        ("1.000000000000000000e+00 2.5e+00 3.0e+00\n", "spaces", 1),
        ("x y z\n1 2 3\n", "spaces", 1),
        ("x,y,z\n1,2,3\n1 2 3\n", "spaces", 3),
        ("0.2;0.2;0.1\n", "`;`", 1),
        ("0.2\t0.2\t0.1\n", "tabs", 1),
    ] {
        let message = message_of(text);
        assert!(
            message.contains(&format!("line {line}:")) && message.contains(separator),
            "{text:?}: {message}"
        );
        assert!(!message.contains("header"), "{text:?}: {message}");
    }
    assert!(message_of("x,y\n").contains("2 fields"));
    assert!(message_of("1,2,3\n4\n").contains("1 field,"));
}

/// Files with classic Mac line ends (CR alone) read whole, and their errors name the right line
/// (all were line 1). A `#` comment in such a file ended only at a `\n`: it swallowed every row
/// after it, and the file read as fewer points without a word.
#[test]
fn carriage_return_line_ends_count_as_lines() {
    assert_eq!(
        points("x,y,z\r1,2,3\r-0.5,1e-300,4e6\r").unwrap(),
        vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(-0.5, 1e-300, 4e6)]
    );
    assert_eq!(line_of("x,y,z\r1,2,3\r1,a,3\r"), 3);
    assert_eq!(line_of("x,y,z\r\n1,2,3\r\n\r\n1,a,3\r\n"), 4);
    assert_eq!(line_of("x,y,z\r1,2,3\r\r# note\r1,a,3\r"), 5);
    assert_eq!(
        points("# contact points\rx,y,z\r1,2,3\r# more\r4,5,6\r").unwrap(),
        vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(4.0, 5.0, 6.0)]
    );
}

/// A UTF-16 file (Excel's "Unicode text") was refused as binary data for its NUL bytes, and as
/// a mesh with an escaped byte soup: the message now names the encoding.
#[test]
fn utf16_files_are_named_as_such() {
    let dir = tempfile::tempdir().unwrap();
    for (bom, encode) in [
        ([0xFF, 0xFE], u16::to_le_bytes as fn(u16) -> [u8; 2]),
        ([0xFE, 0xFF], u16::to_be_bytes),
    ] {
        let path = dir.path().join("points.csv");
        let mut bytes = bom.to_vec();
        bytes.extend("x,y,z\n1,2,3\n".encode_utf16().flat_map(encode));
        std::fs::write(&path, &bytes).unwrap();
        let message = read_points(&path).unwrap_err().to_string();
        assert!(
            message.contains("points.csv") && message.contains("UTF-16"),
            "{message}"
        );
        let mesh = dir.path().join("mesh.vtu");
        let mut bytes = bom.to_vec();
        bytes.extend(
            "<VTKFile type=\"UnstructuredGrid\">"
                .encode_utf16()
                .flat_map(encode),
        );
        std::fs::write(&mesh, &bytes).unwrap();
        let message = cgcontact_io::read_mesh(&mesh, &cgcontact_io::DisplacementArray::Default)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("mesh.vtu") && message.contains("UTF-16"),
            "{message}"
        );
    }
}

/// Regression: numbers were written in plain decimals whatever their size: `locate --gap` on a
/// body of spacing 1e-80 wrote its closest points in about 90 characters each, 5e-324 took 327
/// and 1e300 took 301. Beyond [1e-4, 1e16) they are now written in exponent form, still the
/// shortest digits that read back bitwise; within it, as before.
#[test]
fn numbers_are_short_and_read_back_bitwise() {
    for (x, text) in [
        (5e-324, "5e-324"),
        (1e300, "1e300"),
        (-1.25e-81, "-1.25e-81"),
        (1e16, "1e16"),
        (9.9e-5, "9.9e-5"),
        (1e-4, "0.0001"),
        (0.1, "0.1"),
        (9_999_999_999_999_998.0, "9999999999999998"),
        (0.0, "0"),
        (-0.0, "-0"),
        (f64::INFINITY, "inf"),
        (f64::NAN, "NaN"),
    ] {
        assert_eq!(Num(x).to_string(), text);
    }
    // Every bit pattern class: subnormal, tiny, huge, in range; written and read back bitwise.
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut longest = 0;
    let mut xs = Vec::new();
    for _ in 0..20_000 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let x = f64::from_bits(seed);
        if x.is_finite() {
            xs.push(x);
            longest = longest.max(Num(x).to_string().len());
        }
    }
    assert!(longest <= 24, "{longest} characters");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("points.csv");
    let pts: Vec<DVec3> = xs
        .chunks_exact(3)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect();
    write_points(&path, &pts).unwrap();
    let back = read_points(&path).unwrap();
    assert_eq!(back.len(), pts.len());
    for (a, b) in back.iter().zip(&pts) {
        assert_eq!(
            a.to_array().map(f64::to_bits),
            b.to_array().map(f64::to_bits)
        );
    }
}

/// Numbers with a decimal comma (`"1,5"`, quoted as spreadsheets write them in many locales)
/// were "not a number" without the reason, and a file of one such row was "no data rows": its
/// row was taken for a header. Both now name the comma and the number it would be.
#[test]
fn decimal_commas_are_named_with_the_number_meant() {
    for (text, line, meant) in [
        ("\"1,5\",\"2,5\",\"3,5\"\n", 1, "`1.5`"),
        (
            "\"1,5\",\"2,5\",\"3,5\"\n\"4,5\",\"5,5\",\"6,5\"\n",
            1,
            "`1.5`",
        ),
        ("x,y,z\n1,2,3\n4,\"-0,25e3\",6\n", 3, "`-0.25e3`"),
    ] {
        let message = message_of(text);
        assert!(
            message.contains(&format!("line {line}:"))
                && message.contains("decimal comma")
                && message.contains(meant),
            "{text:?}: {message}"
        );
    }
    // Not numbers with a decimal comma: no such hint, and a header stays a header.
    for text in ["x,\"1,000,000\",z\n", "x,\",5\",z\n", "x,\"y,z\",z\n"] {
        assert!(
            !message_of(&format!("x,y,z\n{text}")).contains("decimal"),
            "{text:?}"
        );
    }
    assert_eq!(
        points("\"x,1\",\"y,2\",\"z,3\"\n1,2,3\n").unwrap(),
        vec![DVec3::new(1.0, 2.0, 3.0)]
    );
}
