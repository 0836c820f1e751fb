//! Volume properties of meshed solids against closed forms: a box cut into six
//! tetrahedra (exact to round-off), the icosahedral symmetry of the sphere meshes
//! (isotropic inertia), and linear and quadratic meshes of one level (the same solid).

// Tensor components read best with their indices.
#![allow(clippy::needless_range_loop)]

use fdem_mesh::{ElementOrder, Sizing, SphereSpec, Surface, TetMesh, sphere_mesh};

/// A box `[x0, x0 + a] x [y0, y0 + b] x [z0, z0 + c]` cut into the six tetrahedra of
/// the Kuhn triangulation (each along the diagonal from corner 0 to corner 7).
fn box_mesh(origin: [f64; 3], size: [f64; 3]) -> TetMesh {
    let corner =
        |i: usize| [0, 1, 2].map(|k| origin[k] + if i >> k & 1 == 1 { size[k] } else { 0.0 });
    let nodes: Vec<[f64; 3]> = (0..8).map(corner).collect();
    // Paths 0 -> 7 through the cube's edges, one per permutation of the axes.
    let mut elements = Vec::new();
    for perm in [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ] {
        let a = 1 << perm[0];
        let b = a | 1 << perm[1];
        let tet = [0, a, b, 7];
        // Orient positively.
        let [p, q, r, s] = tet.map(|i| nodes[i]);
        let v = fdem_mesh::geometry::tet_signed_volume(p, q, r, s);
        elements.extend(if v > 0.0 { tet } else { [0, b, a, 7] });
    }
    TetMesh {
        order: ElementOrder::Linear,
        nodes,
        elements,
        surface: Surface::default(),
    }
}

fn close(a: f64, b: f64, scale: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * scale
}

/// A box: `V = abc`, centroid at the middle, `S = V diag(a^2, b^2, c^2) / 12`, and the
/// inertia `rho V (b^2 + c^2) / 12` about x (likewise y, z), no products of inertia.
/// Placed 1 km from the origin so the shift to the centroid is exercised; 1e-10 relative
/// for round-off.
#[test]
fn a_box_has_its_closed_form_volume_centroid_and_inertia() {
    let (origin, size) = ([1000.0, -2000.0, 500.0], [0.3, 0.2, 0.1]);
    let p = box_mesh(origin, size).volume_properties();
    let v = size[0] * size[1] * size[2];
    assert!(close(p.volume, v, v, 1e-12), "{}", p.volume);
    for k in 0..3 {
        let c = origin[k] + 0.5 * size[k];
        assert!(close(p.centroid[k], c, size[k], 1e-9), "{:?}", p.centroid);
    }
    let rho = 2650.0;
    let inertia = p.inertia(rho);
    let [a2, b2, c2] = size.map(|s| s * s);
    let expected = [b2 + c2, a2 + c2, a2 + b2].map(|s| rho * v * s / 12.0);
    for j in 0..3 {
        for k in 0..3 {
            let e = if j == k { expected[j] } else { 0.0 };
            assert!(
                close(inertia[j][k], e, expected[0], 1e-10),
                "I[{j}][{k}] = {} vs {e}",
                inertia[j][k]
            );
        }
    }
}

/// The sphere meshes have icosahedral symmetry, and a solid with that symmetry has an
/// isotropic inertia tensor: equal diagonal entries and no products of inertia (1e-12
/// relative), centroid at the centre. As the mesh is refined the inertia tends to the
/// sphere's `2/5 m R^2`; the inscribed polyhedron's is below it. Linear and quadratic
/// meshes of a level share their corner tetrahedra, hence their volume properties.
#[test]
fn sphere_meshes_have_isotropic_inertia_that_converges_to_the_sphere() {
    let mut previous = f64::INFINITY;
    for level in 0..=4 {
        let spec = |order| SphereSpec {
            level,
            order,
            diameter: 2.0,
            sizing: Sizing::Inscribed,
        };
        let linear = sphere_mesh(&spec(ElementOrder::Linear)).unwrap();
        let p = linear.volume_properties();
        assert!(close(p.volume, linear.volume(), p.volume, 1e-13));
        assert!(
            p.centroid.iter().all(|c| c.abs() < 1e-13),
            "{:?}",
            p.centroid
        );
        let i = p.inertia(1.0);
        for j in 0..3 {
            for k in 0..3 {
                let e = if j == k { i[0][0] } else { 0.0 };
                assert!(close(i[j][k], e, i[0][0], 1e-12), "level {level}: {i:?}");
            }
        }
        // Relative to the sphere of the mesh's own volume (R^3 = 3V / 4 pi).
        let r2 = (3.0 * p.volume / (4.0 * std::f64::consts::PI)).powf(2.0 / 3.0);
        let error = (i[0][0] / (0.4 * p.volume * r2) - 1.0).abs();
        assert!(error < previous, "level {level}: {error} after {previous}");
        previous = error;
        let quadratic = sphere_mesh(&spec(ElementOrder::Quadratic)).unwrap();
        let q = quadratic.volume_properties();
        assert!(close(q.volume, p.volume, p.volume, 1e-13));
        let iq = q.inertia(1.0);
        assert!(close(iq[0][0], i[0][0], i[0][0], 1e-12));
        eprintln!("level {level}: inertia / (2/5 m R_V^2) - 1 = {error:.3e}");
    }
    assert!(previous < 1e-6, "{previous}");
}

/// A sphere template stretched by axes `[a, b, c]` is an ellipsoid mesh: its volume is
/// the sphere mesh's times `abc` (1e-13) and its second moment the sphere's stretched,
/// `S_kk = abc axes_k^2 S_sphere,kk` (1e-12), the map being affine; the surface's control areas
/// are those of the stretched triangles; the inertia converges with the level to the
/// ellipsoid's `m (b^2 + c^2) r^2 / 5` (the mesh's own volume as reference, as for the
/// sphere). Axes that are not finite and positive are refused.
#[test]
fn a_stretched_sphere_mesh_is_an_ellipsoid_with_its_closed_form_inertia() {
    let axes = [1.0, 0.7, 0.5];
    let mut previous = f64::INFINITY;
    for level in 1..=4 {
        for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
            let sphere = sphere_mesh(&SphereSpec {
                level,
                order,
                diameter: 2.0,
                sizing: Sizing::Inscribed,
            })
            .unwrap();
            let ellipsoid = sphere.stretched(axes).unwrap();
            ellipsoid.validate().unwrap();
            let (s, e) = (sphere.volume_properties(), ellipsoid.volume_properties());
            let abc = axes.iter().product::<f64>();
            assert!(close(e.volume, abc * s.volume, s.volume, 1e-13));
            for k in 0..3 {
                let expected = abc * axes[k] * axes[k] * s.second_moment[k][k];
                let m = e.second_moment[k][k];
                assert!(
                    close(m, expected, expected, 1e-12),
                    "{k}: {m} vs {expected}"
                );
            }
            let area: f64 = ellipsoid
                .surface
                .triangles
                .iter()
                .map(|&[a, b, c]| {
                    let (p, q, r) = (ellipsoid.nodes[a], ellipsoid.nodes[b], ellipsoid.nodes[c]);
                    let u = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                    let v = [r[0] - p[0], r[1] - p[1], r[2] - p[2]];
                    let n = [
                        u[1] * v[2] - u[2] * v[1],
                        u[2] * v[0] - u[0] * v[2],
                        u[0] * v[1] - u[1] * v[0],
                    ];
                    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
                })
                .sum();
            assert!(close(ellipsoid.surface.area(), area, area, 1e-12));
            if order == ElementOrder::Linear {
                // The ellipsoid of the mesh's own volume: semi-axes axes_k * r_V.
                let r2 = (3.0 * e.volume / (4.0 * std::f64::consts::PI * abc)).powf(2.0 / 3.0);
                let i = e.inertia(1.0);
                let exact = e.volume * (axes[1] * axes[1] + axes[2] * axes[2]) * r2 / 5.0;
                let error = (i[0][0] / exact - 1.0).abs();
                eprintln!("level {level}: I_xx / (m (b^2 + c^2) r_V^2 / 5) - 1 = {error:.3e}");
                assert!(error < previous, "level {level}: {error} after {previous}");
                previous = error;
            }
        }
    }
    assert!(previous < 1e-6, "{previous}");
    let sphere = sphere_mesh(&SphereSpec::paper(1.0)).unwrap();
    for bad in [[0.0, 1.0, 1.0], [1.0, -0.5, 1.0], [1.0, 1.0, f64::NAN]] {
        let e = sphere.stretched(bad).unwrap_err();
        assert!(e.to_string().contains("axes"), "{e}");
    }
}
