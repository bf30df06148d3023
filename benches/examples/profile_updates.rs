//! What a solver's displacement update costs on an adaptive body: `check_constraints`,
//! `fill_hanging`, `update_independent` (each independent node scaled by 1.0001, the hanging ones
//! filled) and `set_displacements`, each called 10 times, best time printed. On the `adaptive`
//! bench's seed block refined 2 levels (57,904 nodes), or with `big` its 1,317,692-node body.
//!
//! Run: `cargo run --release -p cgcontact-benches --example profile_updates [big]`

use std::time::{Duration, Instant};

use cgcontact::glam::DVec3;
use cgcontact_scenes::adaptive_block;

fn main() -> Result<(), cgcontact::Error> {
    let big = std::env::args().skip(1).any(|a| a == "big");
    let scene = if big {
        adaptive_block([60, 120, 60], DVec3::splat(0.25 / 3.0), 2, 1.5, 0, 7)?
    } else {
        adaptive_block([20, 40, 20], DVec3::splat(0.25), 2, 1.5, 0, 7)?
    };
    let mut body = scene.body;
    println!(
        "{} nodes, {} hanging",
        body.node_count(),
        body.hanging_nodes().count()
    );
    let u0 = body.displacements().to_vec();
    let mut best = [Duration::MAX; 4];
    let mut time = |slot: usize, f: &mut dyn FnMut()| {
        let t = Instant::now();
        f();
        best[slot] = best[slot].min(t.elapsed());
    };
    for _ in 0..10 {
        let mut holds = false;
        time(0, &mut || holds = body.check_constraints(1e-9).holds());
        assert!(holds, "the scene's hanging nodes obey their constraints");
        time(1, &mut || body.fill_hanging());
        let mut update = Ok(());
        time(2, &mut || {
            update = body.update_independent(|node, _, u| *u = u0[node] * 1.0001);
        });
        update?;
        let mut set = Ok(());
        time(3, &mut || set = body.set_displacements(&u0));
        set?;
    }
    println!(
        "best of 10: check_constraints {:?}, fill_hanging {:?}, update_independent {:?}, set_displacements {:?}",
        best[0], best[1], best[2], best[3]
    );
    Ok(())
}
