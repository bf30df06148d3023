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
    let root = SVGBackend::with_string(&mut svg, (800, 880)).into_drawing_area();
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
    let (root, key) = root.split_vertically(800);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{}: the block's top seen from above, cells shaded by the contact points they hold",
                scene.name
            ),
            ("sans-serif", 16),
        )
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
            faces.push((quad, shade(count, most)));
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
    // A length scale: a bar of a round length, a fifth of the width or less, in the bottom left.
    let width = x1 - x0;
    let bar = 10f64.powf((width / 5.0).log10().floor());
    let bar = [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * bar)
        .find(|&b| b <= width / 5.0)
        .unwrap_or(bar);
    let (bx, by) = (x0 + 0.05 * width, y0 + 0.05 * (y1 - y0));
    chart
        .draw_series([PathElement::new(
            vec![(bx, by), (bx + bar, by)],
            BLACK.stroke_width(3),
        )])
        .map_err(|e| fail(&e))?;
    chart
        .draw_series([Text::new(
            format!("{bar} (model units: h = {})", lattice.h().x),
            (bx, by + 0.02 * (y1 - y0)),
            ("sans-serif", 13).into_font(),
        )])
        .map_err(|e| fail(&e))?;

    // The key: the shades of the cells, and the points.
    let entries: Vec<(String, ShapeStyle, bool)> = [0, 1, most.div_ceil(2), most]
        .into_iter()
        .filter(|&n| n <= most)
        .map(|n| {
            let label = if n == 0 {
                "no point".to_owned()
            } else {
                format!("{n} point{}", if n == 1 { "" } else { "s" })
            };
            (label, shade(n, most).filled(), false)
        })
        .chain([
            (
                "contact point located".to_owned(),
                RGBColor(200, 0, 0).filled(),
                true,
            ),
            (
                "not located".to_owned(),
                RGBColor(150, 150, 150).filled(),
                true,
            ),
        ])
        .collect();
    let mut at = 20;
    for (label, style, point) in entries {
        if point {
            key.draw(&Circle::new((at + 8, 30), 4, style))
                .map_err(|e| fail(&e))?;
        } else {
            key.draw(&Rectangle::new([(at, 22), (at + 16, 38)], style))
                .map_err(|e| fail(&e))?;
            key.draw(&Rectangle::new(
                [(at, 22), (at + 16, 38)],
                RGBColor(120, 120, 120).stroke_width(1),
            ))
            .map_err(|e| fail(&e))?;
        }
        key.draw(&Text::new(
            label.clone(),
            (at + 22, 24),
            ("sans-serif", 13).into_font(),
        ))
        .map_err(|e| fail(&e))?;
        at += 30 + 7 * label.len() as i32;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}

/// The shade of a column holding `count` of at most `most` located points.
fn shade(count: u32, most: u32) -> RGBColor {
    if count == 0 {
        RGBColor(245, 245, 245)
    } else {
        let t = 0.3 + 0.7 * f64::from(count) / f64::from(most.max(1));
        RGBColor(
            255,
            (230.0 * (1.0 - t)) as u8 + 20,
            (120.0 * (1.0 - t)) as u8,
        )
    }
}
