//! Renumbers the particles of a prepared specimen along the Morton curve of their current
//! centres (within each run of one size class, which the specimen keeps in order), with
//! the same state: node positions and velocities, rigid poses and the tangential history
//! follow their particles. The renumbered specimen is the same packing in another body
//! order, to time what the order alone costs (docs/PERFORMANCE.md, "Numbering the
//! particles along a space-filling curve").
//!
//! `cargo run --release -p fdem-triaxial --example renumber_specimen -- IN OUT [--identity]`
//! (`--identity` writes the same order, through the same path, as the control).
use fdem_contact::Counterpart;
use fdem_core::space_order::morton_order;
use fdem_triaxial::PreparedSpecimen;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (input, output) = match (args.first(), args.get(1)) {
        (Some(i), Some(o)) => (i, o),
        _ => return Err("usage: renumber_specimen IN OUT [--identity]".into()),
    };
    let identity = args.iter().any(|a| a == "--identity");
    let mut p = PreparedSpecimen::load(std::path::Path::new(input))?;
    let n = p.particles.len();
    let nodes = p.state.positions.len();
    if n == 0 || nodes % n != 0 {
        return Err(format!("{nodes} nodes do not split evenly over {n} particles").into());
    }
    let per = nodes / n;
    let rigid = !p.state.rigid.is_empty();
    if rigid && p.state.rigid.len() != n {
        return Err("a mixed specimen is not supported".into());
    }
    let centre = |b: usize| -> [f64; 3] {
        let mut c = [0.0; 3];
        for x in &p.state.positions[b * per..(b + 1) * per] {
            for d in 0..3 {
                c[d] += x[d] / per as f64;
            }
        }
        c
    };
    // new_to_old[k]: the old body numbered k.
    let mut new_to_old = Vec::with_capacity(n);
    let mut start = 0;
    while start < n {
        let class = p.particles[start].class;
        let end = start
            + p.particles[start..]
                .iter()
                .take_while(|q| q.class == class)
                .count();
        let centres: Vec<[f64; 3]> = (start..end).map(centre).collect();
        if identity {
            new_to_old.extend(start..end);
        } else {
            new_to_old.extend(morton_order(&centres).into_iter().map(|i| start + i));
        }
        start = end;
    }
    let mut old_to_new = vec![0usize; n];
    for (k, &o) in new_to_old.iter().enumerate() {
        old_to_new[o] = k;
    }
    p.particles = new_to_old.iter().map(|&o| p.particles[o].clone()).collect();
    let block = |v: &[[f64; 3]]| -> Vec<[f64; 3]> {
        new_to_old
            .iter()
            .flat_map(|&o| v[o * per..(o + 1) * per].iter().copied())
            .collect()
    };
    p.state.positions = block(&p.state.positions);
    p.state.velocities = block(&p.state.velocities);
    if rigid {
        p.state.rigid = new_to_old.iter().map(|&o| p.state.rigid[o]).collect();
    }
    for h in &mut p.state.history {
        let (b, i) = (h.0 / per, h.0 % per);
        if b < n {
            h.0 = old_to_new[b] * per + i;
        }
        if let Counterpart::Body(c) = h.1
            && (c as usize) < n
        {
            h.1 = Counterpart::Body(old_to_new[c as usize] as u32);
        }
    }
    p.state.history.sort_by_key(|h| (h.0, h.1.code()));
    p.save(std::path::Path::new(output))?;
    println!(
        "{n} particles, {per} nodes each, renumbered{}",
        if identity { " (identity)" } else { "" }
    );
    Ok(())
}
