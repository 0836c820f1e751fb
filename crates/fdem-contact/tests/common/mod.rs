//! Scene builders shared by the test binaries.
#![allow(dead_code)]

use fdem_contact::{ContactModel, ContactParams, ContactSurface, Wall};
use fdem_mesh::{ElementOrder, MeshAssembly, Placement, Sizing, SphereSpec, TetMesh, sphere_mesh};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

pub fn rng(seed: u64) -> Pcg64 {
    Pcg64::seed_from_u64(seed)
}

pub fn linear_sphere(level: u32, diameter: f64) -> TetMesh {
    sphere_mesh(&SphereSpec {
        level,
        order: ElementOrder::Linear,
        diameter,
        sizing: Sizing::Inscribed,
    })
    .expect("valid sphere spec")
}

pub fn random_rotation(rng: &mut Pcg64) -> [f64; 4] {
    loop {
        let q: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if n > 0.1 && n < 1.0 {
            return q.map(|c| c / n);
        }
    }
}

pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    a.map(|c| c * s)
}

pub fn random_unit(rng: &mut Pcg64) -> [f64; 3] {
    loop {
        let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = norm(v);
        if n > 0.1 && n < 1.0 {
            return scale(v, 1.0 / n);
        }
    }
}

/// Depth of `x` inside the convex body `b` of `assembly` (min over its faces of the distance
/// behind the face plane), or a negative number outside.
pub fn depth_inside(assembly: &MeshAssembly, b: usize, x: [f64; 3]) -> f64 {
    let range = assembly.bodies[b].surface_triangles.clone();
    assembly.triangles[range]
        .iter()
        .map(|t| {
            let [a, p, q] = t.map(|i| assembly.nodes[i]);
            let n = cross(sub(p, a), sub(q, a));
            -dot(sub(x, a), n) / norm(n)
        })
        .fold(f64::MAX, f64::min)
}

/// Deepest penetration of a surface node of one body into the other (m); negative when
/// the two bodies are apart.
pub fn max_penetration(assembly: &MeshAssembly) -> f64 {
    let mut deepest = f64::MIN;
    for (b, other) in [(0, 1), (1, 0)] {
        for &i in &assembly.surface_nodes[assembly.bodies[b].surface_nodes.clone()] {
            deepest = deepest.max(depth_inside(assembly, other, assembly.nodes[i]));
        }
    }
    deepest
}

/// Two-body assembly of `mesh` at the two placements.
pub fn pair_of(mesh: &TetMesh, a: &Placement, b: &Placement) -> MeshAssembly {
    let mut assembly = MeshAssembly::new();
    assembly.push_instance(mesh, a).expect("placement");
    assembly.push_instance(mesh, b).expect("placement");
    assembly
}

/// A randomly rotated copy of `mesh` placed along a random direction from `anchor` so that
/// the deepest surface node of one is `depth` (m) inside the other (a negative `depth` is
/// a gap), by bisection on the distance of the centres (`mesh` has diameter `d`).
pub fn place_near(
    rng: &mut Pcg64,
    mesh: &TetMesh,
    d: f64,
    anchor: &Placement,
    depth: f64,
) -> Placement {
    let rotation = random_rotation(rng);
    let u = random_unit(rng);
    let at = |s: f64| Placement {
        scale: 1.0,
        rotation,
        translation: add(anchor.translation, scale(u, s)),
    };
    // Penetration decreases as the centres move apart.
    let (mut lo, mut hi) = (0.5 * d, 1.1 * d);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if max_penetration(&pair_of(mesh, anchor, &at(mid))) > depth {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    at(0.5 * (lo + hi))
}

/// Two randomly rotated spheres of diameter `d` so that the deepest surface node of one is
/// `depth` (m) inside the other.
pub fn overlapping_pair(rng: &mut Pcg64, level: u32, d: f64, depth: f64) -> MeshAssembly {
    let mesh = linear_sphere(level, d);
    let anchor = Placement {
        scale: 1.0,
        rotation: random_rotation(rng),
        translation: [0.0; 3],
    };
    let other = place_near(rng, &mesh, d, &anchor, depth);
    pair_of(&mesh, &anchor, &other)
}

/// A model over an assembly with uniform node masses.
pub fn model_for(
    assembly: &MeshAssembly,
    params: ContactParams,
    walls: Vec<Wall>,
    mass: f64,
    margin: Option<f64>,
) -> ContactModel {
    let surface = ContactSurface::from_assembly(assembly).expect("surface");
    let margin = margin
        .unwrap_or_else(|| ContactModel::suggested_margin(&surface, &assembly.nodes).unwrap());
    ContactModel::new(
        params,
        surface,
        walls,
        &vec![mass; assembly.n_nodes()],
        margin,
    )
    .expect("model")
}
