//! Cost of a test step against the contact settings (docs/TRIAXIAL.md, "Contact depth
//! limit"): builds the test around a prepared specimen for each (skin, depth limit) pair,
//! both in units of the specimen's contact margin, and times 300 steps.
//!
//! `cargo run --release -p fdem-triaxial --example step_cost -- SPECIMEN [SKIN DEPTH]...`
//! (defaults: the test's own settings, 0.25 and 2; `STEPS=N` in the environment times N
//! steps instead of 300). The steps run on a worker of the global pool, as in `fdem`.
use fdem_triaxial::{PreparedSpecimen, TEST_SKIN_FRACTION, TestModel};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: step_cost SPECIMEN [SKIN DEPTH]...")?;
    let prepared = PreparedSpecimen::load(std::path::Path::new(path))?;
    let margin = {
        let model = TestModel::build(&prepared, None)?;
        model.sim.contact().ok_or("no contact")?.model().margin() / TEST_SKIN_FRACTION
    };
    let mut pairs: Vec<(f64, f64)> = args[1..]
        .chunks(2)
        .map(|p| Ok((p[0].parse()?, p.get(1).ok_or("a depth per skin")?.parse()?)))
        .collect::<Result<_, Box<dyn std::error::Error>>>()?;
    if pairs.is_empty() {
        pairs.push((TEST_SKIN_FRACTION, 2.0));
    }
    let h = prepared.spec.coarse_graining;
    for (skin, depth) in pairs {
        let mut p = prepared.clone();
        // The test's skin is TEST_SKIN_FRACTION of the specimen margin; lengths in the
        // definition are multiplied by h.
        p.spec.contact.margin = Some(skin * margin / TEST_SKIN_FRACTION / h);
        p.spec.contact.depth_limit = Some(depth * margin / h);
        let mut model = TestModel::build(&p, None)?;
        for _ in 0..20 {
            model.sim.advance()?;
        }
        let steps: usize = std::env::var("STEPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(300);
        // Timed on a worker of the pool, as the command line runs its time loops.
        let clock = Instant::now();
        rayon::scope(|_| (0..steps).try_for_each(|_| model.sim.advance()))?;
        let seconds = clock.elapsed().as_secs_f64() / steps as f64;
        let c = model.sim.contact().ok_or("no contact")?;
        let r = c.last_report();
        println!(
            "skin {:.2} mm, depth limit {:.2} mm: {:.3} ms per step, {} candidate pairs, \
             {} node contacts, {} rebuilds",
            1e3 * c.model().margin(),
            1e3 * c.model().depth_limit(),
            1e3 * seconds,
            r.candidate_pairs,
            r.contacts,
            c.model().rebuild_count()
        );
    }
    Ok(())
}
