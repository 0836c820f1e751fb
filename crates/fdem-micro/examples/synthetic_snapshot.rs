//! Writes a synthetic E2-size snapshot (1,872 particles, about 4 x 10^4 node rows) with
//! its ground truth into `OUT_DIR/contacts/` and times the clustering:
//!
//! ```text
//! cargo run --release -p fdem-micro --example synthetic_snapshot -- OUT_DIR [SEED [label-free]]
//! ```

use fdem_micro::synthetic::{SyntheticSpec, generate};
use fdem_micro::{
    ClusterParams, cluster, read_nodes, read_pairs, statistics, validate, write_nodes, write_pairs,
};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = std::path::PathBuf::from(
        args.first()
            .ok_or("usage: synthetic_snapshot OUT_DIR [SEED [label-free]]")?,
    );
    let seed: u64 = args.get(1).map_or(Ok(1), |s| s.parse())?;
    let mut spec = SyntheticSpec::e2(seed);
    spec.labelled = args.get(2).is_none_or(|s| s != "label-free");
    let data = generate(&spec);
    let folder = out.join("contacts");
    std::fs::create_dir_all(&folder)?;
    write_nodes(&folder.join("nodes_000000.csv"), &data.snapshot)?;
    write_pairs(&folder.join("pairs_000000.csv"), 0.0, &data.truth)?;
    // Best of five clusterings of the in-memory snapshot.
    let params = ClusterParams::default();
    let mut best = f64::INFINITY;
    let mut result = None;
    for _ in 0..5 {
        let start = Instant::now();
        let c = cluster(&data.snapshot, &params)?;
        best = best.min(start.elapsed().as_secs_f64());
        result = Some(c);
    }
    let c = result.ok_or("no run")?;
    // Best of five reads of the written files.
    let mut read = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        let s = read_nodes(&folder.join("nodes_000000.csv"))?;
        let t = read_pairs(&folder.join("pairs_000000.csv"))?;
        read = read.min(start.elapsed().as_secs_f64());
        assert_eq!(
            (s.rows.len(), t.len()),
            (data.snapshot.rows.len(), data.truth.len())
        );
    }
    let s = statistics(&c, Some(data.particles));
    let v = validate(&c, &data.truth, 0.01);
    println!(
        "{} particles, {} node rows, {} particle contacts generated; clustered {} particle + {} \
         boundary contacts in {:.1} ms (best of 5; reading the two CSV files {:.1} ms); \
         body-pair recall {:?}, precision {:?}, max force error {:?}",
        data.particles,
        data.snapshot.rows.len(),
        data.particle_contacts,
        s.contacts,
        s.boundary_contacts,
        1e3 * best,
        1e3 * read,
        v.body_pairs.recall,
        v.body_pairs.precision,
        v.body_pairs.max_force_error
    );
    Ok(())
}
