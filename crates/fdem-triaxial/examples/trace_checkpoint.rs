//! Traces a test step by step from a checkpoint: for diagnosing an event (a guard that
//! stopped the test, a particle thrown out) from shortly before it.
//!
//! `cargo run --release -p fdem-triaxial --example trace_checkpoint -- SPECIMEN CHECKPOINT
//! STEPS [EVERY]` resumes the test model of the prepared `SPECIMEN` at `CHECKPOINT` (a
//! `checkpoint.fdemckpt` of the same definition) and advances it `STEPS` steps, printing
//! every `EVERY` steps (default 100) and at every step where the fastest particle node
//! moves faster than twice the last print's: the step, the time, the fastest particle
//! node (speed, body), the kinetic energy of the particles, the deepest contact and the
//! fastest membrane node's speed. It
//! stops at the first error and prints it. The platens keep the motion they had at the
//! checkpoint, as in shear.
use fdem_triaxial::{PreparedSpecimen, TestModel};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: trace_checkpoint SPECIMEN CHECKPOINT STEPS [EVERY]";
    let (Some(specimen), Some(checkpoint), Some(steps)) = (args.first(), args.get(1), args.get(2))
    else {
        return Err(usage.into());
    };
    let steps: u64 = steps.parse()?;
    let every: u64 = args.get(3).map_or(Ok(100), |s| s.parse())?;
    let prepared = PreparedSpecimen::load(Path::new(specimen))?;
    let mut model = TestModel::at_checkpoint(&prepared, Path::new(checkpoint))?;
    let particle_nodes = model.membrane().first_node();
    let body_of: Vec<usize> = {
        let mut b = vec![0; particle_nodes];
        for (id, body) in model.sim.bodies().iter().enumerate() {
            for n in body.nodes.clone().filter(|&n| n < particle_nodes) {
                b[n] = id;
            }
        }
        b
    };
    let mut last_speed = 0.0f64;
    println!("step,time,max_speed,node,body,kinetic_energy,max_depth,membrane_max_speed");
    for k in 1..=steps {
        if let Err(e) = model.sim.advance() {
            println!("error at step {}: {e}", model.sim.step());
            return Ok(());
        }
        let v = &model.sim.state().velocities[..particle_nodes];
        let (node, speed) = v
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .enumerate()
            .fold(
                (0, 0.0),
                |best, (i, s)| if s > best.1 { (i, s) } else { best },
            );
        if k % every == 0 || speed > 2.0 * last_speed {
            let kinetic = model.sim.state().kinetic_energy(0..particle_nodes);
            let depth = model
                .sim
                .contact()
                .map_or(0.0, |c| c.last_report().max_depth);
            let membrane = model.sim.state().velocities[particle_nodes..]
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
                .fold(0.0, f64::max);
            println!(
                "{},{:e},{speed:e},{node},{},{kinetic:e},{depth:e},{membrane:e}",
                model.sim.step(),
                model.sim.time(),
                body_of[node]
            );
            last_speed = speed;
        }
    }
    Ok(())
}
