//! Warm starts against the cold search, as the C and Python bindings call them (1,024 points a
//! call), for instruction counts: the answers of a first `locate_all_into` are the hints, then
//! every piece is located again cold (`locate`) or warm from its hints (`relocate`), on one
//! thread.
//!
//! Run: `cargo run --release -p cgcontact-benches --example profile_warm [block|adaptive-block|sphere|sphere-adaptive|gaps] [locate|relocate|gap|regap]`
//! (`block`: the seed's fine block and 100,000 known points; `adaptive-block`: the `adaptive`
//! bench's block refined twice, 100,000 known points; `sphere`, `sphere-adaptive`: the seed's
//! scenes, uniform or refined, with 100,000 random points over the box of their contact and
//! known points, a quarter of them outside the body). Without `locate` or `relocate` only the
//! first pass runs: the baseline to subtract. Instructions of the pieces:
//! `valgrind --tool=callgrind --toggle-collect='cgcontact::schedule::Scheduler::run*'
//! target/release/examples/profile_warm adaptive-block relocate`, less the same without
//! `relocate`.
//!
//! `gaps [gap|regap]`: the seed's 6,700 sphere points on its fine block, their gaps within h
//! measured cold (`gap_all_into`) or warm from the faces of a first pass (`regap_all`), ten
//! times over, in the same pieces.

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveLocator, LatticeLocator, Locator, Settings};
use cgcontact_scenes::{SphereOnAdaptiveBlock, SphereOnBlock, adaptive_block, indented_block};

/// Points per call, as the bindings' pieces.
const PIECE: usize = 1024;
const POINTS: usize = 100_000;

/// `POINTS` random points over the box of `points` (a fixed sequence).
fn spread(points: &[DVec3]) -> Vec<DVec3> {
    let (mut low, mut high) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for p in points {
        (low, high) = (low.min(*p), high.max(*p));
    }
    let mut state = 1u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..POINTS)
        .map(|_| low + DVec3::new(next(), next(), next()) * (high - low))
        .collect()
}

/// The pool every measured call runs in: one thread, as the other profiling examples.
fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool")
}

fn run(locator: &dyn Locator, points: &[DVec3], mode: Option<&str>) {
    let one = one_thread();
    let mut hints = Vec::new();
    one.install(|| locator.locate_all_into(points, &mut hints));
    let located = hints.iter().filter(|a| matches!(a, Ok(Some(_)))).count();
    println!("{located} of {} points located", points.len());
    let mut out = Vec::with_capacity(PIECE);
    for (piece, hints) in points.chunks(PIECE).zip(hints.chunks(PIECE)) {
        out.clear();
        out.extend_from_slice(hints);
        let piece = std::hint::black_box(piece);
        match mode {
            Some("locate") => one.install(|| locator.locate_all_into(piece, &mut out)),
            Some("relocate") => one.install(|| locator.relocate_all(piece, &mut out)),
            _ => {}
        }
    }
}

fn main() -> Result<(), cgcontact::Error> {
    let args: Vec<String> = std::env::args().collect();
    let has = |flag: &str| args.iter().any(|a| a == flag);
    let mode = ["locate", "relocate", "gap", "regap"]
        .into_iter()
        .find(|m| has(m));
    let settings = Settings::default();
    if has("gaps") {
        let scene = SphereOnBlock::fine().build("sphere")?;
        let locator = LatticeLocator::new(&scene.body, settings)?;
        let finder = cgcontact::GapFinder::new(&locator, scene.body.lattice().h().z)?;
        let points = &scene.contact_points;
        let one = one_thread();
        let mut hints = Vec::new();
        one.install(|| finder.gap_all_into(points, &mut hints));
        let found = hints.iter().filter(|a| matches!(a, Ok(Some(_)))).count();
        println!("{found} of {} points within the distance", points.len());
        let mut out = Vec::with_capacity(PIECE);
        for _ in 0..10 {
            for (piece, hints) in points.chunks(PIECE).zip(hints.chunks(PIECE)) {
                out.clear();
                out.extend_from_slice(hints);
                let piece = std::hint::black_box(piece);
                match mode {
                    Some("gap") => one.install(|| finder.gap_all_into(piece, &mut out)),
                    Some("regap") => one.install(|| finder.regap_all(piece, &mut out)),
                    _ => {}
                }
            }
        }
        return Ok(());
    }
    if has("adaptive-block") {
        let scene = adaptive_block([20, 40, 20], DVec3::splat(0.25), 2, 1.5, POINTS, 7)?;
        let points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        run(&AdaptiveLocator::new(&scene.body, settings)?, &points, mode);
    } else if has("sphere-adaptive") {
        let scene = SphereOnAdaptiveBlock::fine().build("sphere-adaptive")?;
        let points = spread(&scene.all_points());
        run(&AdaptiveLocator::new(&scene.body, settings)?, &points, mode);
    } else if has("sphere") {
        let scene = SphereOnBlock::fine().build("sphere")?;
        let mut points = scene.contact_points.clone();
        points.extend(scene.known.iter().map(|k| k.x));
        run(
            &LatticeLocator::new(&scene.body, settings)?,
            &spread(&points),
            mode,
        );
    } else {
        let scene = indented_block([20, 40, 20], DVec3::splat(0.25), POINTS, 7)?;
        let points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        run(&LatticeLocator::new(&scene.body, settings)?, &points, mode);
    }
    Ok(())
}
