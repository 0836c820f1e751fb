//! Writes the paper's particle (level 1, quadratic, d = 15 mm) and a few variants as VTK
//! files, for a look in ParaView: `cargo run -p fdem-mesh --example write_particle -- DIR`.

use std::path::PathBuf;

use fdem_mesh::{
    CellNodes, ElementOrder, MeshAssembly, MeshError, Placement, Sizing, SphereSpec, VtuFrame,
    sphere_mesh, write_pvd, write_vtu,
};

fn main() -> Result<(), MeshError> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".to_string()));
    let quadratic = sphere_mesh(&SphereSpec::paper(0.015))?;
    let linear = sphere_mesh(&SphereSpec {
        order: ElementOrder::Linear,
        sizing: Sizing::VolumeEquivalent,
        ..SphereSpec::paper(0.015)
    })?;
    quadratic.write_vtu(&dir.join("particle_quadratic.vtu"))?;
    linear.write_vtu(&dir.join("particle_linear.vtu"))?;

    let triangles: Vec<usize> = quadratic
        .surface
        .triangles
        .iter()
        .flatten()
        .copied()
        .collect();
    write_vtu(
        &dir.join("surface.vtu"),
        &VtuFrame {
            points: &quadratic.nodes,
            cells: &triangles,
            cell_nodes: CellNodes::Uniform(3),
            point_fields: vec![],
            cell_fields: vec![],
        },
    )?;

    let mut assembly = MeshAssembly::new();
    for k in 0..3 {
        assembly.push_instance(&quadratic, &Placement::at([0.02 * k as f64, 0.0, 0.0]))?;
    }
    assembly.write_vtu(&dir.join("assembly.vtu"))?;
    write_pvd(
        &dir.join("particles.pvd"),
        &[
            (0.0, "particle_quadratic.vtu".to_string()),
            (1.0, "assembly.vtu".to_string()),
        ],
    )?;
    println!("{:#?}", quadratic.quality());
    Ok(())
}
