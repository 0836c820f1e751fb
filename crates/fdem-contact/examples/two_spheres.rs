//! Contact forces between two overlapping particle meshes, with nothing but fdem-mesh and
//! fdem-contact: `cargo run -p fdem-contact --example two_spheres`.
//!
//! Two paper particles (level 1, quadratic, d = 15 mm) are stacked along z with 20 um of
//! overlap and the lower one also rests on a rigid floor; one evaluation prints every node
//! contact, the pair sums, the wall force and the contact stable time step.

use fdem_contact::{ContactModel, ContactParams, ContactSurface, Counterpart, Wall};
use fdem_mesh::{MeshAssembly, Placement, SphereSpec, sphere_mesh};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let d = 0.015;
    let particle = sphere_mesh(&SphereSpec::paper(d))?;
    let mut assembly = MeshAssembly::new();
    assembly.push_instance(&particle, &Placement::at([0.0, 0.0, 0.0]))?;
    assembly.push_instance(&particle, &Placement::at([0.0, 0.0, d - 2e-5]))?;
    let lowest = assembly.nodes.iter().map(|x| x[2]).fold(f64::MAX, f64::min);
    // The floor is 10 um above the lowest node, so that node is pushed up.
    let floor = Wall::plane([0.0, 0.0, lowest + 1e-5], [0.0, 0.0, 1.0]);

    // Lumped masses would come from fdem-elastic; a uniform share of rock mass will do here.
    let volume = particle.volume();
    let node_mass = 2650.0 * volume / particle.n_nodes() as f64;
    let masses = vec![node_mass; assembly.n_nodes()];

    let surface = ContactSurface::from_assembly(&assembly)?;
    let margin = ContactModel::suggested_margin(&surface, &assembly.nodes)
        .ok_or("the assembly has no surface triangles")?;
    let mut contact = ContactModel::new(
        ContactParams::default(),
        surface,
        vec![floor],
        &masses,
        margin,
    )?;

    let velocities = vec![[0.0; 3]; assembly.n_nodes()];
    let mut forces = vec![[0.0; 3]; assembly.n_nodes()];
    let report = contact.add_forces(&assembly.nodes, &velocities, 0.0, 1e-7, &mut forces)?;

    println!(
        "margin {margin:.3e} m, cell size {:.3e} m",
        contact.cell_size()
    );
    println!("{report:#?}");
    for c in contact.node_contacts() {
        let against = match c.counterpart {
            Counterpart::Body(b) => format!("face {:?} of body {b}", c.face),
            Counterpart::Wall(w) => format!("wall {w}"),
        };
        println!(
            "node {:4} (body {}) against {against}: depth {:.3e} m, F_n {:?} N",
            c.node, c.body, c.depth, c.normal_force
        );
    }
    for p in contact.pair_sums() {
        println!(
            "body {} <- {:?}: {} nodes, normal {:?} N",
            p.body, p.counterpart, p.nodes, p.normal_force
        );
    }
    println!("force on the floor: {:?} N", contact.wall_forces()[0]);
    if let Some(step) = contact.stable_time_step() {
        println!("{step}");
    }
    Ok(())
}
