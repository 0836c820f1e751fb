//! The cost of the test's escape check (`TestModel::particles_outside`) at a checkpoint:
//! for measuring a change of it on a real specimen (run it with the old and the new
//! binary; the same particles must come out).
//!
//! `cargo run --release -p fdem-triaxial --example escape_check_cost -- SPECIMEN CHECKPOINT
//! [REPEATS]` resumes the test model of the prepared `SPECIMEN` at `CHECKPOINT` and runs
//! the check `REPEATS` times (default 5), printing the wall milliseconds of each and the
//! particles found outside. `RAYON_NUM_THREADS` sets the threads (default: all cores).
use fdem_triaxial::{PreparedSpecimen, TestModel};
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(specimen), Some(checkpoint)) = (args.first(), args.get(1)) else {
        return Err("usage: escape_check_cost SPECIMEN CHECKPOINT [REPEATS]".into());
    };
    let repeats: usize = args.get(2).map_or(Ok(5), |r| r.parse())?;
    let prepared = PreparedSpecimen::load(Path::new(specimen))?;
    let mut model = TestModel::at_checkpoint(&prepared, Path::new(checkpoint))?;
    // On a worker of the pool, as the command line runs the check (`&mut`: the model is
    // `Send`, not `Sync`).
    let model = &mut model;
    rayon::scope(move |_| {
        for _ in 0..repeats {
            let t = Instant::now();
            let outside = model.particles_outside();
            let ms = t.elapsed().as_secs_f64() * 1e3;
            println!("{ms:.1} ms, outside: {outside:?}");
        }
    });
    Ok(())
}
