//! Newton inversions per located point of the lattice locator on scenes of growing difficulty.
//!
//! Run: `cargo run --release -p cgcontact-benches --example inversions`

use cgcontact::glam::DVec3;
use cgcontact::{CandidateOrder, LatticeLocator, Locator, Settings};
use cgcontact_scenes::SphereOnBlock;

fn main() -> Result<(), cgcontact::Error> {
    let cases = [
        ("fine, sink 0.45 h", SphereOnBlock::fine()),
        (
            "fine, sink 0.45 h, jitter 0.3 h",
            SphereOnBlock {
                jitter: 0.3,
                ..SphereOnBlock::fine()
            },
        ),
        (
            "coarse, sink 3 h",
            SphereOnBlock {
                sink_in_h: 3.0,
                ..SphereOnBlock::coarse()
            },
        ),
        (
            "coarse, sink 3 h, jitter 0.4 h",
            SphereOnBlock {
                sink_in_h: 3.0,
                jitter: 0.4,
                ..SphereOnBlock::coarse()
            },
        ),
        (
            "fine, anisotropic 1:4, sink 2 h",
            SphereOnBlock {
                h: DVec3::new(0.25, 0.5, 0.0625),
                sink_in_h: 2.0,
                ..SphereOnBlock::fine()
            },
        ),
    ];
    println!("| scene | order | located / known | inversions per point | iterations per point |");
    println!("|---|---|---|---|---|");
    for (name, knobs) in cases {
        let scene = knobs.build(name)?;
        for order in [CandidateOrder::Predicted, CandidateOrder::Undeformed] {
            let locator = LatticeLocator::new(
                &scene.body,
                Settings {
                    order,
                    ..Settings::default()
                },
            )?;
            let hits: Vec<_> = scene
                .known
                .iter()
                .filter_map(|k| locator.locate(k.x).ok().flatten())
                .collect();
            let inversions: u64 = hits.iter().map(|h| u64::from(h.inversions)).sum();
            let iterations: u64 = hits.iter().map(|h| u64::from(h.iterations)).sum();
            println!(
                "| {name} | {order:?} | {} / {} | {:.4} | {:.3} |",
                hits.len(),
                scene.known.len(),
                inversions as f64 / hits.len() as f64,
                iterations as f64 / hits.len() as f64
            );
        }
    }
    Ok(())
}
