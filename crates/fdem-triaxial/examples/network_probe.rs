//! Where the explicit step of a rigid specimen really fails, against the contact network's
//! step (docs/MODEL.md section 12): resumes the test model of a prepared `SPECIMEN` at
//! `CHECKPOINT` and one step further, fixes the step at `FACTOR` times the network's step
//! at that state (`Simulation::rigid_network_step`), and
//! advances `STEPS` steps, printing the energy balance error every `STEPS / 10` steps; one
//! CSV row per factor at the end: factor, dt (s), the network's step (s) and its source, the
//! rigorous bound (`Simulation::rigid_network_bound`, s), steps done, the largest relative
//! balance error seen, and how it ended (`completed` or the error). It also prints the
//! estimate's time and `2 / omega` after 400 Lanczos steps (its convergence).
//!
//! `cargo run --release -p fdem-triaxial --example network_probe -- SPECIMEN CHECKPOINT
//! STEPS THREADS FACTOR [FACTOR ...]`
use fdem_triaxial::{PreparedSpecimen, TestModel};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: network_probe SPECIMEN CHECKPOINT STEPS THREADS FACTOR [FACTOR ...]";
    if args.len() < 5 {
        return Err(usage.into());
    }
    let steps: u64 = args[2].parse()?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(args[3].parse()?)
        .build_global()?;
    let factors: Vec<f64> = args[4..]
        .iter()
        .map(|f| f.parse())
        .collect::<Result<_, _>>()?;
    let prepared = PreparedSpecimen::load(Path::new(&args[0]))?;
    let mut rows = Vec::new();
    for factor in factors {
        let mut model = TestModel::at_checkpoint(&prepared, Path::new(&args[1]))?;
        // One step at the run's own step first: a restored history carries no contact
        // points, and the bound reads the contacts of the last evaluation.
        model.sim.advance()?;
        let t = std::time::Instant::now();
        let bound = model
            .sim
            .rigid_network_step()
            .ok_or("no rigid contacts at the checkpoint")?;
        let seconds = t.elapsed().as_secs_f64();
        let rigorous = model.sim.rigid_network_bound().map_or(f64::NAN, |b| b.dt);
        let converged = model
            .sim
            .rigid_network_frequency(400)
            .map_or(f64::NAN, |omega| 2.0 / omega);
        eprintln!(
            "network step {:e} s in {seconds:.3} s ({}); the bound {rigorous:e} s; 2 / omega \
             after 400 Lanczos steps {converged:e} s",
            bound.dt, bound.source
        );
        model.sim.fix_dt(factor * bound.dt)?;
        let (mut done, mut worst, mut ended) = (0, 0.0f64, "completed".to_string());
        // On a worker of the pool, as the command line runs its time loops.
        rayon::scope(|_| {
            for k in 1..=steps {
                if let Err(e) = model.sim.advance() {
                    ended = e.to_string().replace(',', ";");
                    break;
                }
                done = k;
                if k % (steps / 10).max(1) == 0 {
                    let error = model.sim.relative_balance_error(&model.sim.energy());
                    worst = worst.max(error);
                    eprintln!("factor {factor}: step {k}, balance error {error:.3e}");
                }
            }
        });
        rows.push(format!(
            "{factor},{:e},{:e},{},{rigorous:e},{done},{worst:e},{ended}",
            model.sim.dt(),
            bound.dt,
            bound.source.replace(',', ";")
        ));
    }
    println!("factor,dt,network_step,source,rigorous_bound,steps,max_balance_error,ended");
    for r in rows {
        println!("{r}");
    }
    Ok(())
}
