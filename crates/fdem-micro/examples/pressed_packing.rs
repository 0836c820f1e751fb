//! Runs a small packing squeezed between six walls with contact snapshots on, so that
//! `fdem micro DIR` has a real run directory to analyse:
//!
//! ```text
//! cargo run --release -p fdem-micro --example pressed_packing -- OUT_DIR [NX NY NZ [SPEED DURATION PENALTY PITCH]]
//! ```

#[path = "../tests/common/mod.rs"]
mod common;

use fdem_solver::{RunOptions, Scene, Silent, run};
use std::sync::atomic::AtomicBool;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args
        .first()
        .ok_or("usage: pressed_packing OUT_DIR [NX NY NZ]")?;
    let mut grid = [3usize, 3, 3];
    for (g, a) in grid.iter_mut().zip(args.iter().skip(1)) {
        *g = a.parse()?;
    }
    let speed: f64 = args.get(4).map_or(Ok(1.0), |a| a.parse())?;
    let duration: f64 = args.get(5).map_or(Ok(3.0e-4), |a| a.parse())?;
    let penalty: f64 = args.get(6).map_or(Ok(1.8e11), |a| a.parse())?;
    let pitch: f64 = args.get(7).map_or(Ok(1.0), |a| a.parse())?;
    let text = common::pressed_packing(grid, pitch, speed, penalty, duration, 6);
    let scene = Scene::from_toml_str(&text, "pressed_packing")?;
    let options = RunOptions {
        out_dir: out.into(),
        vtk: false,
        contacts: true,
    };
    let summary = run(&scene, &options, &mut Silent, &AtomicBool::new(false))?;
    eprintln!(
        "{} steps, {} outputs, {:.2} s wall time: {out}",
        summary.steps, summary.outputs, summary.wall_seconds
    );
    Ok(())
}
