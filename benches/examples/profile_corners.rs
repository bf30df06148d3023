//! What computing a leaf's corner nodes costs against reading them from the corner table: every
//! leaf of the `adaptive` bench's seed block (refined 2 levels), in a fixed random order, asked for
//! its corner nodes (`AdaptiveBody::cell_nodes`) 20 times, on a body without and a body with
//! `set_corner_table(true)`, alternated 4 times. The sums printed show that both answer alike.
//!
//! Run: `cargo run --release -p cgcontact-benches --example profile_corners`

use std::time::Instant;

use cgcontact::CellId;
use cgcontact::glam::DVec3;
use cgcontact_scenes::adaptive_block;

fn main() -> Result<(), cgcontact::Error> {
    let scene = adaptive_block([20, 40, 20], DVec3::splat(0.25), 2, 1.5, 0, 7)?;
    let computed = scene.body;
    let mut tabled = computed.clone();
    tabled.set_corner_table(true);
    let n = computed.cell_count() as u32;
    // A fixed linear congruential shuffle: the same order on every run.
    let mut ids: Vec<u32> = (0..n).collect();
    let mut state = 1u64;
    for i in (1..ids.len()).rev() {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ids.swap(i, (state >> 33) as usize % (i + 1));
    }
    for _ in 0..4 {
        for (name, body) in [("computed", &computed), ("corner table", &tabled)] {
            let start = Instant::now();
            let mut sum = 0usize;
            for _ in 0..20 {
                for &id in &ids {
                    let nodes = body.cell_nodes(CellId(id)).expect("a leaf");
                    sum = sum.wrapping_add(nodes.iter().sum::<usize>());
                }
            }
            let ns = start.elapsed().as_secs_f64() * 1e9 / (20.0 * f64::from(n));
            println!("{name}: {ns:.1} ns per leaf (sum {sum})");
        }
    }
    Ok(())
}
