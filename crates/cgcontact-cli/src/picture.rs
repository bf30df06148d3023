//! The contact patch picture (the seed's figures 38–39): the top of the block seen from above, the
//! cells holding located points shaded, the contact points drawn over them; on an adaptive body,
//! each cell outlined in its level's colour.

use std::path::Path;

use anyhow::{Result, anyhow};
use cgcontact::glam::DVec3;
use cgcontact::{Answer, CellId, GapAnswer};
use cgcontact_scenes::{AdaptiveScene, Scene};
use plotters::prelude::*;

/// One top face to draw: its deformed corners seen from above, the located points its cell (or
/// column) holds, and its refinement level.
struct Face {
    quad: Vec<(f64, f64)>,
    held: u32,
    level: u8,
}

/// What the picture shows, whatever the body.
struct Patch<'a> {
    /// Each contact point's gap to the block's surface (`None`: farther than the search distance).
    gaps: &'a [GapAnswer],
    /// The search distance of `gaps`.
    distance: f64,
    name: &'a str,
    sphere: (DVec3, f64),
    contact_points: &'a [DVec3],
    /// The (base) spacing along x, for the length scale's caption.
    h: f64,
    faces: Vec<Face>,
    levels: u8,
}

/// Write `path` (SVG): the deformed top face of every column of cells, shaded by how many located
/// points the column holds, and the contact points projected on the x–y plane, coloured by their
/// gap to the block's surface (`gaps`, within `distance`; grey beyond). Only the region around the
/// sphere is drawn.
pub fn contact_patch_svg(
    path: &Path,
    scene: &Scene,
    answers: &[Answer],
    gaps: &[GapAnswer],
    distance: f64,
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
    // Top faces (corners 4, 5, 6, 7 of the top cell of each column), deformed, seen from above.
    let mut faces = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let Some(corners) = body.corners(lattice.cell_id([i, j, nz - 1])) else {
                continue;
            };
            faces.push(Face {
                quad: top_quad(&corners),
                held: held[(i + nx * j) as usize],
                level: 0,
            });
        }
    }
    let patch = Patch {
        gaps,
        distance,
        name: &scene.name,
        sphere: scene.sphere,
        contact_points: &scene.contact_points,
        h: lattice.h().x,
        faces,
        levels: 1,
    };
    draw_svg(path, &patch)
}

/// [`contact_patch_svg`] for an adaptive scene: the top face of every leaf on the block's top,
/// shaded by the located points the leaf holds, outlined in its level's colour.
pub fn adaptive_patch_svg(
    path: &Path,
    scene: &AdaptiveScene,
    answers: &[Answer],
    gaps: &[GapAnswer],
    distance: f64,
) -> Result<()> {
    let body = &scene.body;
    let top = f64::from(body.lattice().cells()[2]);
    // Counted per column, as the uniform picture does: a located point counts for the top leaf
    // above it (the leaf holding its x, y just under the undeformed top face).
    let top_z = body.lattice().upper().z - 1e-9 * body.spacing(body.finest_level()).z;
    let mut held = vec![0u32; body.cell_count()];
    for (x, answer) in scene.contact_points.iter().zip(answers) {
        if !matches!(answer, Ok(Some(_))) {
            continue;
        }
        if let Some(leaf) = body.leaf_at(DVec3::new(x.x, x.y, top_z)) {
            held[leaf.index()] += 1;
        }
    }
    let faces = body
        .leaves()
        .iter()
        .enumerate()
        .filter(|(_, leaf)| f64::from(leaf.ijk[2] + 1) * 0.5f64.powi(i32::from(leaf.level)) == top)
        .filter_map(|(id, leaf)| {
            let corners = body.corners(CellId(id as u32))?;
            Some(Face {
                quad: top_quad(&corners),
                held: held[id],
                level: leaf.level,
            })
        })
        .collect();
    let patch = Patch {
        gaps,
        distance,
        name: &scene.name,
        sphere: scene.sphere,
        contact_points: &scene.contact_points,
        h: body.lattice().h().x,
        faces,
        levels: body.finest_level() + 1,
    };
    draw_svg(path, &patch)
}

/// Corners 4, 5, 6, 7 (the top face) seen from above.
fn top_quad(corners: &[DVec3; 8]) -> Vec<(f64, f64)> {
    [4, 5, 6, 7]
        .iter()
        .map(|&c| (corners[c].x, corners[c].y))
        .collect()
}

/// The outline of a face of `level`: grey for the base level, then a colour per level.
fn outline(level: u8) -> RGBColor {
    match level {
        0 => RGBColor(120, 120, 120),
        1 => RGBColor(30, 90, 200),
        2 => RGBColor(0, 140, 70),
        _ => RGBColor(150, 40, 170),
    }
}

fn draw_svg(path: &Path, patch: &Patch<'_>) -> Result<()> {
    let mut svg = String::new();
    let root = SVGBackend::with_string(&mut svg, (800, 880)).into_drawing_area();
    draw_contact_patch(root, path, patch)?;
    crate::output::write_text(path, &svg)
}

/// [`contact_patch_svg`]'s drawing, on `root`.
fn draw_contact_patch(
    root: DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    path: &Path,
    patch: &Patch<'_>,
) -> Result<()> {
    let most = patch.faces.iter().map(|f| f.held).max().unwrap_or(0).max(1);
    let (center, radius) = patch.sphere;
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
                "{}: the block's top seen from above, cells shaded by the points they hold, points by gap",
                patch.name
            ),
            ("sans-serif", 16),
        )
        .margin(10)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| fail(&e))?;

    let inside = |quad: &[(f64, f64)]| {
        !quad
            .iter()
            .all(|&(x, y)| x < x0 || x > x1 || y < y0 || y > y1)
    };
    let faces: Vec<&Face> = patch.faces.iter().filter(|f| inside(&f.quad)).collect();
    chart
        .draw_series(
            faces
                .iter()
                .map(|f| Polygon::new(f.quad.clone(), shade(f.held, most).filled())),
        )
        .map_err(|e| fail(&e))?;
    // Outlines coarsest first, so that a fine cell's edge on a coarse one shows its level.
    let mut outlined = faces.clone();
    outlined.sort_by_key(|f| f.level);
    chart
        .draw_series(outlined.iter().map(|f| {
            let mut ring = f.quad.clone();
            ring.push(f.quad[0]);
            PathElement::new(ring, outline(f.level).stroke_width(1))
        }))
        .map_err(|e| fail(&e))?;

    // Contact points on the lower half of the sphere, the side facing the block, coloured by gap:
    // red shades inside the block (the deepest the darkest), blue shades apart, grey beyond the
    // search distance. Drawn far to near, so that the penetrating points show on top.
    let deepest = patch
        .gaps
        .iter()
        .filter_map(|g| g.ok().flatten())
        .map(|c| -c.gap)
        .fold(0.0, f64::max);
    let mut shown: Vec<(DVec3, Option<f64>)> = patch
        .contact_points
        .iter()
        .zip(
            patch
                .gaps
                .iter()
                .map(|g| g.ok().flatten().map(|c| c.gap))
                .chain(std::iter::repeat(None)),
        )
        .filter(|(x, _)| x.z <= center.z)
        .map(|(x, g)| (*x, g))
        .collect();
    shown.sort_by(|a, b| {
        let key = |g: Option<f64>| g.unwrap_or(f64::INFINITY);
        key(b.1).total_cmp(&key(a.1))
    });
    chart
        .draw_series(shown.iter().map(|(x, g)| {
            let (colour, size) = match g {
                None => (RGBColor(170, 170, 170), 1),
                Some(g) => (gap_colour(*g, deepest, patch.distance), 2),
            };
            Circle::new((x.x, x.y), size, colour.filled())
        }))
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
            format!(
                "{bar} (model units: {}h = {})",
                if patch.levels > 1 { "base " } else { "" },
                patch.h
            ),
            (bx, by + 0.02 * (y1 - y0)),
            ("sans-serif", 13).into_font(),
        )])
        .map_err(|e| fail(&e))?;

    // The key: the shades of the cells, and the points.
    // On an adaptive body, each level's outline.
    let levels = (0..patch.levels)
        .filter(|_| patch.levels > 1)
        .map(|l| (format!("level {l}"), outline(l).stroke_width(3), false));
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
        .chain(
            [
                (format!("gap {:.3}", -deepest), -deepest),
                ("gap 0".to_owned(), 0.0),
                (format!("gap {}", patch.distance), patch.distance),
            ]
            .into_iter()
            // No penetration: no key for it.
            .filter(|&(_, g)| deepest > 0.0 || g >= 0.0)
            .map(|(label, g)| (label, gap_colour(g, deepest, patch.distance).filled(), true)),
        )
        .chain([(
            format!("beyond {}", patch.distance),
            RGBColor(170, 170, 170).filled(),
            true,
        )])
        .chain(levels)
        .collect();
    let (mut at, mut row) = (20, 0);
    for (label, style, point) in entries {
        let width = 30 + 7 * label.len() as i32;
        if at + width > 800 {
            (at, row) = (20, row + 28);
        }
        if point {
            key.draw(&Circle::new((at + 8, 30 + row), 4, style))
                .map_err(|e| fail(&e))?;
        } else {
            key.draw(&Rectangle::new(
                [(at, 22 + row), (at + 16, 38 + row)],
                style,
            ))
            .map_err(|e| fail(&e))?;
            key.draw(&Rectangle::new(
                [(at, 22 + row), (at + 16, 38 + row)],
                RGBColor(120, 120, 120).stroke_width(1),
            ))
            .map_err(|e| fail(&e))?;
        }
        key.draw(&Text::new(
            label.clone(),
            (at + 22, 24 + row),
            ("sans-serif", 13).into_font(),
        ))
        .map_err(|e| fail(&e))?;
        at += width;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}

/// The colour of a contact point of gap `gap`: from yellow at 0 to dark red at `-deepest` inside
/// the block, from light to dark blue at `distance` apart.
fn gap_colour(gap: f64, deepest: f64, distance: f64) -> RGBColor {
    let mix = |a: (f64, f64, f64), b: (f64, f64, f64), t: f64| {
        let t = t.clamp(0.0, 1.0);
        RGBColor(
            (a.0 + (b.0 - a.0) * t) as u8,
            (a.1 + (b.1 - a.1) * t) as u8,
            (a.2 + (b.2 - a.2) * t) as u8,
        )
    };
    if gap < 0.0 {
        mix(
            (255.0, 200.0, 0.0),
            (170.0, 0.0, 0.0),
            -gap / deepest.max(f64::MIN_POSITIVE),
        )
    } else {
        mix(
            (120.0, 200.0, 255.0),
            (0.0, 50.0, 190.0),
            gap / distance.max(f64::MIN_POSITIVE),
        )
    }
}

/// The shade of a column holding `count` of at most `most` located points: greens, so that the
/// points' gap colours (reds and blues) stand out on them.
fn shade(count: u32, most: u32) -> RGBColor {
    if count == 0 {
        RGBColor(245, 245, 245)
    } else {
        let t = 0.3 + 0.7 * f64::from(count) / f64::from(most.max(1));
        RGBColor(
            (235.0 - 120.0 * t) as u8,
            (240.0 - 60.0 * t) as u8,
            (225.0 - 120.0 * t) as u8,
        )
    }
}
