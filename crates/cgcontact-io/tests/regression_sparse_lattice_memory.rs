//! A 704-byte file with 3 active cells on a 400³ lattice took 2.28 GB and 5 s: one slot per lattice
//! node, a dense displacement field, a table per lattice cell. Memory now grows with the cells.
//! (Alone in its test binary: the process's peak memory is this test's.)

use cgcontact::glam::DVec3;
use cgcontact::{LatticeLocator, Locator, Settings};
use cgcontact_io::{DisplacementArray, HexMesh, parse_hex_mesh};

/// Peak resident memory of this process (Linux), in bytes.
fn peak_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Three unit cells at far corners of a 400³ lattice of spacing 0.5, as an XML file (ascii).
fn three_cells() -> (Vec<u8>, Vec<[u32; 3]>) {
    let lows = vec![[0, 0, 0], [399, 0, 0], [0, 399, 399]];
    let mut mesh = HexMesh::default();
    let mut u = Vec::new();
    for low in &lows {
        let base = mesh.points.len() as u32;
        for [a, b, c] in cgcontact::CORNER_OFFSETS {
            let p = DVec3::new(
                f64::from(low[0] + a),
                f64::from(low[1] + b),
                f64::from(low[2] + c),
            ) * 0.5;
            mesh.points.push(p);
            u.push(DVec3::new(0.01 * p.z, 0.0, -0.02));
        }
        mesh.cells.push(std::array::from_fn(|k| base + k as u32));
    }
    mesh.displacement = Some(u);
    let n = mesh.cells.len();
    let join = |v: Vec<String>| v.join(" ");
    let f = |v: &[DVec3]| {
        join(
            v.iter()
                .flat_map(|p| p.to_array())
                .map(|x| x.to_string())
                .collect(),
        )
    };
    let xml = format!(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n<UnstructuredGrid><Piece NumberOfPoints=\"{}\" NumberOfCells=\"{n}\">\n<PointData><DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray></PointData>\n<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray></Points>\n<Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">{}</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">{}</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells>\n</Piece></UnstructuredGrid></VTKFile>\n",
        mesh.points.len(),
        f(mesh.displacement.as_ref().unwrap()),
        f(&mesh.points),
        join(mesh.cells.iter().flatten().map(|c| c.to_string()).collect()),
        join((1..=n).map(|c| (8 * c).to_string()).collect()),
        join(vec!["12".to_owned(); n]),
    );
    (xml.into_bytes(), lows)
}

#[test]
fn three_cells_on_a_400_cubed_lattice_take_kilobytes() {
    let (file, lows) = three_cells();
    assert!(file.len() < 4096, "{} bytes", file.len());
    let mesh = parse_hex_mesh(&file, &DisplacementArray::Default)
        .unwrap()
        .to_lattice()
        .unwrap();
    assert_eq!(mesh.body.lattice().cells(), [400, 400, 400]);
    assert_eq!(mesh.body.active_count(), 3);
    let bytes = mesh.body.heap_bytes() + mesh.cells.heap_bytes();
    assert!(
        bytes < 16 << 10,
        "{bytes} bytes for the body and its cell map"
    );
    // Located right: the centre of each cell, displaced by its (uniform in x, y) field.
    let locator = LatticeLocator::new(&mesh.body, Settings::default()).unwrap();
    assert!(locator.heap_bytes() < 16 << 10, "{}", locator.heap_bytes());
    for (input, low) in lows.iter().enumerate() {
        let centre = DVec3::new(
            f64::from(low[0]) + 0.5,
            f64::from(low[1]) + 0.5,
            f64::from(low[2]) + 0.5,
        ) * 0.5;
        let x = centre + DVec3::new(0.01 * centre.z, 0.0, -0.02);
        let hit = locator.locate(x).unwrap().expect("inside its cell");
        assert_eq!(mesh.cells.input_cell(hit.cell), Some(input));
        assert!(hit.xi.abs().max_element() < 1e-9, "{}", hit.xi);
    }
    assert!(locator.locate(DVec3::splat(100.0)).unwrap().is_none());
    if let Some(peak) = peak_rss() {
        assert!(peak < 64 << 20, "peak resident memory {} MB", peak >> 20);
    }
}
