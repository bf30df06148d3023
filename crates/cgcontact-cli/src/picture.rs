//! The contact patch picture (the seed's figures 38–39): the top of the block seen from above, the
//! cells holding located points shaded, the contact points drawn over them.

use std::path::Path;

use anyhow::{Result, anyhow};
use cgcontact::Answer;
use cgcontact_scenes::Scene;
use plotters::prelude::*;

/// Write `path` (SVG): the deformed top face of every column of cells, shaded by how many located
/// points the column holds, and the contact points (located: red; not located: grey) projected on
/// the x–y plane. Only the region around the sphere is drawn.
pub fn contact_patch_svg(path: &Path, scene: &Scene, answers: &[Answer]) -> Result<()> {
    let mut svg = String::new();
    let root = SVGBackend::with_string(&mut svg, (800, 800)).into_drawing_area();
    draw_contact_patch(root, path, scene, answers)?;
    crate::output::write_text(path, &svg)
}

/// [`contact_patch_svg`]'s drawing, on `root`.
fn draw_contact_patch(
    root: DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    path: &Path,
    scene: &Scene,
    answers: &[Answer],
) -> Result<()> {
    let body = &scene.body;
    let lattice = body.lattice();
    let [nx, ny, nz] = lattice.cells();
    let mut held = vec![0u32; (nx * ny) as usize];
    for hit in answers.iter().filter_map(|a| a.ok().flatten()) {
        if let Some([i, j, _]) = lattice.cell_ijk(hit.cell) {
            held[(i + nx * j) as usize] += 1;
        }
    }
    let most = held.iter().copied().max().unwrap_or(0).max(1);
    let (center, radius) = scene.sphere;
    let half = radius * 1.6;
    let (x0, x1, y0, y1) = (
        center.x - half,
        center.x + half,
        center.y - half,
        center.y + half,
    );

    let fail =
        |e: &dyn std::fmt::Display| anyhow!("{}: cannot draw the picture: {e}", path.display());
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| fail(&e))?;

    // Top faces (corners 4, 5, 6, 7 of the top cell of each column), deformed, seen from above.
    let mut faces = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let Some(corners) = body.corners(lattice.cell_id([i, j, nz - 1])) else {
                continue;
            };
            let quad: Vec<(f64, f64)> = [4, 5, 6, 7]
                .iter()
                .map(|&c| (corners[c].x, corners[c].y))
                .collect();
            if quad
                .iter()
                .all(|&(x, y)| x < x0 || x > x1 || y < y0 || y > y1)
            {
                continue;
            }
            let count = held[(i + nx * j) as usize];
            let shade = if count == 0 {
                RGBColor(245, 245, 245)
            } else {
                let t = 0.3 + 0.7 * f64::from(count) / f64::from(most);
                RGBColor(
                    255,
                    (230.0 * (1.0 - t)) as u8 + 20,
                    (120.0 * (1.0 - t)) as u8,
                )
            };
            faces.push((quad, shade));
        }
    }
    chart
        .draw_series(
            faces
                .iter()
                .map(|(quad, shade)| Polygon::new(quad.clone(), shade.filled())),
        )
        .map_err(|e| fail(&e))?;
    chart
        .draw_series(faces.iter().map(|(quad, _)| {
            let mut ring = quad.clone();
            ring.push(quad[0]);
            PathElement::new(ring, RGBColor(120, 120, 120).stroke_width(1))
        }))
        .map_err(|e| fail(&e))?;

    // Contact points on the lower half of the sphere, the side facing the block.
    let shown = scene
        .contact_points
        .iter()
        .zip(answers)
        .filter(|(x, _)| x.z <= center.z);
    let (located, free): (Vec<_>, Vec<_>) = shown.partition(|(_, a)| matches!(a, Ok(Some(_))));
    chart
        .draw_series(
            free.iter()
                .map(|(x, _)| Circle::new((x.x, x.y), 1, RGBColor(150, 150, 150).filled())),
        )
        .map_err(|e| fail(&e))?;
    chart
        .draw_series(
            located
                .iter()
                .map(|(x, _)| Circle::new((x.x, x.y), 2, RGBColor(200, 0, 0).filled())),
        )
        .map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}
