//! The benches' lattices: simple cubic lattices of level-1 linear spheres (d = 15 mm,
//! identity orientation) whose axis vertices overlap their neighbours by 0.3 of the
//! contact margin, with small random velocities, numbered in lattice order or at random in
//! space (`-shuffled`, as a prepared specimen numbers its particles in placement order).

use fdem_contact::{ContactModel, ContactParams, ContactSurface};
use fdem_mesh::{ElementOrder, MeshAssembly, Placement, Sizing, SphereSpec, sphere_mesh};

/// A lattice of spheres with its contact model, ready for `add_forces`.
pub struct Packing {
    pub positions: Vec<[f64; 3]>,
    pub velocities: Vec<[f64; 3]>,
    pub model: ContactModel,
    pub surface_nodes: usize,
}

/// The lattice sites `0..n^3` in the order the bodies are numbered: lattice order, or with
/// `shuffled` a fixed random permutation (xorshift Fisher-Yates), as in a prepared
/// specimen, whose particles are numbered in placement order, at random in space.
fn site_order(n: usize, shuffled: bool) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n * n * n).collect();
    if shuffled {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        for i in (1..order.len()).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            order.swap(i, (state % (i as u64 + 1)) as usize);
        }
    }
    order
}

/// `n^3` spheres on a simple cubic lattice, overlapping by 0.3 margin along the axes,
/// numbered in lattice order or, with `shuffled`, at random.
pub fn packing(n: usize, shuffled: bool) -> Packing {
    let d = 0.015;
    let mesh = sphere_mesh(&SphereSpec {
        level: 1,
        order: ElementOrder::Linear,
        diameter: d,
        sizing: Sizing::Inscribed,
    })
    .expect("sphere");
    let half_extent = mesh.nodes.iter().map(|x| x[0]).fold(f64::MIN, f64::max);
    let template = ContactSurface {
        triangles: mesh.surface.triangles.clone(),
        triangle_body: vec![0; mesh.surface.triangles.len()],
        surface_nodes: mesh.surface.nodes.clone(),
        node_body: vec![0; mesh.surface.nodes.len()],
        control_areas: mesh.surface.control_areas.clone(),
    };
    let margin = ContactModel::suggested_margin(&template, &mesh.nodes).expect("margin");
    let spacing = 2.0 * half_extent - 0.3 * margin;
    let mut assembly = MeshAssembly::new();
    for site in site_order(n, shuffled) {
        let t = [site / (n * n), (site / n) % n, site % n].map(|c| c as f64 * spacing);
        assembly
            .push_instance(&mesh, &Placement::at(t))
            .expect("placement");
    }
    let node_mass = 2650.0 * mesh.volume() / mesh.n_nodes() as f64;
    let masses = vec![node_mass; assembly.n_nodes()];
    // Small deterministic velocities (mm/s) so that damping and friction paths run.
    let velocities = assembly
        .nodes
        .iter()
        .map(|x| x.map(|c| 1e-3 * (c * 1e3).sin()))
        .collect();
    let surface = ContactSurface::from_assembly(&assembly).expect("surface");
    let surface_nodes = surface.n_surface_nodes();
    let model = ContactModel::new(ContactParams::default(), surface, vec![], &masses, margin)
        .expect("model");
    Packing {
        positions: assembly.nodes,
        velocities,
        model,
        surface_nodes,
    }
}

/// Every lattice: side (bodies per axis), label, bodies numbered at random.
pub const LATTICES: [(usize, &str, bool); 5] = [
    (10, "1k", false),
    (20, "8k", false),
    (20, "8k-shuffled", true),
    (40, "64k", false),
    (40, "64k-shuffled", true),
];

/// The lattices the contact bench times: the 64k ones (2.7 M surface nodes, a peak of
/// about 1.2 GB for one in the `build_cost` example) only with `FDEM_BENCH_64K` set.
pub fn sizes() -> Vec<(usize, &'static str, bool)> {
    let large = std::env::var_os("FDEM_BENCH_64K").is_some();
    LATTICES
        .into_iter()
        .filter(|&(side, _, _)| large || side < 40)
        .collect()
}
