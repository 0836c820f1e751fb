//! Energy bookkeeping probe (docs/TRIAXIAL.md, "Energy balance"): builds the test around a
//! prepared specimen, sets a membrane pressure and a top-platen velocity, and prints the
//! balance terms five times over the given number of steps.
//!
//! `cargo run --release -p fdem-triaxial --example energy_probe -- SPECIMEN PRESSURE VELOCITY STEPS`
use fdem_triaxial::{PreparedSpecimen, TestModel};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: energy_probe SPECIMEN PRESSURE(Pa) VELOCITY(m/s) STEPS";
    if args.len() != 4 {
        return Err(usage.into());
    }
    let prepared = PreparedSpecimen::load(std::path::Path::new(&args[0]))?;
    let pressure: f64 = args[1].parse()?;
    let velocity: f64 = args[2].parse()?;
    let steps: usize = args[3].parse()?;
    let mut model = TestModel::build(&prepared, None)?;
    model.set_pressure(pressure);
    model.set_top_velocity(velocity)?;
    model.sim.rebase_energy()?;
    println!("step kinetic strain stored damping friction work balance_error (J)");
    for k in 1..=steps {
        model.sim.advance()?;
        if k % (steps / 5).max(1) == 0 {
            let e = model.sim.energy();
            println!(
                "{k} {:.4} {:.4} {:.4} {:.4} {:.4} {:.4} {:.4}",
                e.kinetic,
                e.strain,
                e.other_potential,
                e.damping_dissipated,
                e.friction_dissipated,
                e.external_work,
                e.balance_error
            );
        }
    }
    Ok(())
}
