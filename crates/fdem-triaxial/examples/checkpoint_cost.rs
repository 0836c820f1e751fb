//! The cost of a test step at a checkpoint, split into steps with a full broad-phase
//! rebuild, with a partial refresh (the bodies that drifted) and with neither, and a
//! checksum of the state reached: for measuring a speed change
//! on a real specimen (run it with the old and the new binary; equal checksums mean the
//! change left the physics bit for bit as it was).
//!
//! `cargo run --release -p fdem-triaxial --example checkpoint_cost -- SPECIMEN CHECKPOINT
//! STEPS [THREADS [DEPTH_LIMIT]]` resumes the test model of the prepared `SPECIMEN` at
//! `CHECKPOINT` (a `checkpoint.fdemckpt` of the same definition), optionally with another
//! contact depth limit (m), advances it `STEPS` steps on `THREADS` threads (default:
//! rayon's default) timing every step, and prints one CSV row: steps,
//! rebuilds, the mean wall milliseconds of steps with and without a rebuild, a rebuild's
//! extra cost in plain steps, the candidate pairs and contacts at the end, the broad phase's
//! cell size and box enlargement (m), the FNV-1a hash of the node positions' bits, the
//! refreshes and the mean milliseconds of a step with one, the mean milliseconds of all
//! steps, and the mean number of bodies a refresh renewed. The platens keep the motion they had at the
//! checkpoint, as in shear. Large blocks are on huge pages, as in the `fdem` binary.
use fdem_triaxial::{PreparedSpecimen, TestModel};
use std::path::Path;
use std::time::Instant;

#[global_allocator]
static ALLOCATOR: fdem_core::huge_pages::HugePages = fdem_core::huge_pages::HugePages;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: checkpoint_cost SPECIMEN CHECKPOINT STEPS [THREADS [DEPTH_LIMIT]]";
    let (Some(specimen), Some(checkpoint), Some(steps)) = (args.first(), args.get(1), args.get(2))
    else {
        return Err(usage.into());
    };
    let steps: u64 = steps.parse()?;
    if let Some(threads) = args.get(3) {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads.parse()?)
            .build_global()?;
    }
    let prepared = PreparedSpecimen::load(Path::new(specimen))?;
    let mut model = TestModel::at_checkpoint(&prepared, Path::new(checkpoint))?;
    if let Some(limit) = args.get(4) {
        let contact = model
            .sim
            .contact_mut()
            .ok_or("the test has no contact model")?;
        contact.model_mut().set_depth_limit(limit.parse()?)?;
    }
    let builds = |m: &TestModel| m.sim.contact().map_or(0, |c| c.model().rebuild_count());
    let refreshes = |m: &TestModel| m.sim.contact().map_or(0, |c| c.model().refresh_count());
    let (mut plain, mut rebuilt, mut refreshed) = ((0u64, 0.0f64), (0u64, 0.0f64), (0u64, 0.0f64));
    let mut refreshed_bodies = 0usize;
    // On a worker of the pool, as the command line runs its time loops (from outside the
    // pool every parallel region of a step would be a hand-over and a wake-up).
    rayon::scope(|_| {
        for _ in 0..steps {
            let before = (builds(&model), refreshes(&model));
            let t = Instant::now();
            model.sim.advance()?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let slot = if builds(&model) > before.0 {
                &mut rebuilt
            } else if refreshes(&model) > before.1 {
                refreshed_bodies += model
                    .sim
                    .contact()
                    .map_or(0, |c| c.last_report().refreshed_bodies);
                &mut refreshed
            } else {
                &mut plain
            };
            slot.0 += 1;
            slot.1 += ms;
        }
        Ok::<(), fdem_solver::SolverError>(())
    })?;
    let mean = |(n, ms): (u64, f64)| if n == 0 { f64::NAN } else { ms / n as f64 };
    let (plain_ms, rebuilt_ms) = (mean(plain), mean(rebuilt));
    let (pairs, contacts, cell, enlargement) = model.sim.contact().map_or((0, 0, 0.0, 0.0), |c| {
        let m = c.model();
        (
            m.candidate_pairs().len(),
            c.last_report().contacts,
            m.cell_size(),
            m.candidate_enlargement(),
        )
    });
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for x in &model.sim.state().positions {
        for v in x {
            for byte in v.to_bits().to_le_bytes() {
                hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    println!(
        "steps,rebuilds,ms_plain,ms_rebuild,rebuild_cost_steps,pairs,contacts,cell_size,enlargement,hash,refreshes,ms_refresh,ms_step,bodies_per_refresh"
    );
    let all_ms = (plain.1 + rebuilt.1 + refreshed.1) / steps.max(1) as f64;
    println!(
        "{steps},{},{plain_ms:.3},{rebuilt_ms:.3},{:.2},{pairs},{contacts},{cell:e},{enlargement:e},{hash:016x},{},{:.3},{all_ms:.3},{:.1}",
        rebuilt.0,
        (rebuilt_ms - plain_ms) / plain_ms,
        refreshed.0,
        mean(refreshed),
        refreshed_bodies as f64 / refreshed.0.max(1) as f64,
    );
    Ok(())
}
