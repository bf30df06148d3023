//! Checks that `locate_all_into` (batched) answers bitwise as `locate` on several scenes.
use cgcontact::glam::DVec3;
use cgcontact::{LatticeLocator, Locator, Settings};
use cgcontact_scenes::SphereOnBlock;

fn main() -> Result<(), cgcontact::Error> {
    let cases = [
        SphereOnBlock::fine(),
        SphereOnBlock {
            jitter: 0.3,
            ..SphereOnBlock::fine()
        },
        SphereOnBlock {
            sink_in_h: 3.0,
            ..SphereOnBlock::coarse()
        },
        SphereOnBlock {
            sink_in_h: 3.0,
            jitter: 0.4,
            ..SphereOnBlock::coarse()
        },
        SphereOnBlock {
            h: DVec3::new(0.25, 0.5, 0.0625),
            sink_in_h: 2.0,
            ..SphereOnBlock::fine()
        },
    ];
    for knobs in cases {
        let scene = knobs.build("x")?;
        let mut points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        points.extend(scene.known.iter().map(|k| k.x + DVec3::splat(0.3)));
        points.push(DVec3::NAN);
        points.push(DVec3::splat(1e9));
        for settings in [Settings::default(), Settings::f32()] {
            let locator = LatticeLocator::new(&scene.body, settings)?;
            let all = locator.locate_all(&points);
            let mut differ = 0;
            for (x, a) in points.iter().zip(&all) {
                let b = locator.locate(*x);
                let same = match (a, &b) {
                    (Ok(Some(p)), Ok(Some(q))) => {
                        p.cell == q.cell
                            && p.xi.to_array().map(f64::to_bits)
                                == q.xi.to_array().map(f64::to_bits)
                            && p.iterations == q.iterations
                            && p.residual.to_bits() == q.residual.to_bits()
                            && p.inversions == q.inversions
                    }
                    _ => a == &b,
                };
                if !same {
                    differ += 1;
                    if differ < 3 {
                        println!("{x}: {a:?} vs {b:?}");
                    }
                }
            }
            println!(
                "{:?}: {} points, {} differ",
                settings.precision,
                points.len(),
                differ
            );
        }
    }
    Ok(())
}
