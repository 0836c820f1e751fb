//! Placement of template meshes into global arrays.

use approx::assert_relative_eq;
use fdem_mesh::geometry::{distance, tet_signed_volume};
use fdem_mesh::{
    ElementOrder, MeshAssembly, MeshError, Placement, Sizing, SphereSpec, TetMesh, sphere_mesh,
};
use proptest::prelude::*;

fn template(level: u32, order: ElementOrder) -> TetMesh {
    sphere_mesh(&SphereSpec {
        level,
        order,
        diameter: 0.015,
        sizing: Sizing::Inscribed,
    })
    .unwrap()
}

/// Unit quaternion for a rotation of `angle` about `axis`.
fn axis_angle(axis: [f64; 3], angle: f64) -> [f64; 4] {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let s = (angle / 2.0).sin() / n;
    [(angle / 2.0).cos(), axis[0] * s, axis[1] * s, axis[2] * s]
}

fn body_volume(a: &MeshAssembly, body: usize) -> f64 {
    a.bodies[body]
        .elements
        .clone()
        .map(|e| {
            let el = a.element(e).unwrap();
            tet_signed_volume(
                a.nodes[el[0]],
                a.nodes[el[1]],
                a.nodes[el[2]],
                a.nodes[el[3]],
            )
        })
        .sum()
}

#[test]
fn placed_instances_scale_rotate_and_offset() {
    let t = template(1, ElementOrder::Quadratic);
    let mut a = MeshAssembly::new();
    assert_eq!(a.n_elements(), 0);
    let placements = [
        Placement::identity(),
        Placement {
            scale: 2.0,
            rotation: axis_angle([1.0, 2.0, 3.0], 0.7),
            translation: [0.1, -0.2, 0.3],
        },
        Placement {
            scale: 0.5,
            rotation: axis_angle([0.0, 0.0, 1.0], 3.0),
            translation: [-1.0, 0.0, 2.0],
        },
    ];
    for (b, p) in placements.iter().enumerate() {
        assert_eq!(a.push_instance(&t, p).unwrap(), b);
    }
    let (nn, ne, nt, ns) = (
        t.n_nodes(),
        t.n_elements(),
        t.surface.triangles.len(),
        t.surface.nodes.len(),
    );
    assert_eq!(a.order, Some(ElementOrder::Quadratic));
    assert_eq!(a.n_bodies(), 3);
    assert_eq!(a.n_nodes(), 3 * nn);
    assert_eq!(a.n_elements(), 3 * ne);
    assert_eq!(a.triangles.len(), 3 * nt);
    assert_eq!(a.triangle_body.len(), 3 * nt);
    assert_eq!(a.surface_nodes.len(), 3 * ns);
    assert_eq!(a.control_areas.len(), 3 * ns);

    let tv = t.volume();
    let tq = t.quality();
    for (b, p) in placements.iter().enumerate() {
        let r = &a.bodies[b];
        assert_eq!(r.nodes, b * nn..(b + 1) * nn);
        assert_eq!(r.elements, b * ne..(b + 1) * ne);
        assert_eq!(r.surface_triangles, b * nt..(b + 1) * nt);
        assert_eq!(r.surface_nodes, b * ns..(b + 1) * ns);
        let off = b * nn;
        // Indices offset by the nodes before this body.
        for e in 0..ne {
            let global = a.element(b * ne + e).unwrap();
            let local = t.element(e);
            assert!(global.iter().zip(local).all(|(&g, &l)| g == l + off));
        }
        for k in 0..nt {
            assert_eq!(
                a.triangles[b * nt + k],
                t.surface.triangles[k].map(|i| i + off)
            );
            assert_eq!(a.triangle_body[b * nt + k], b as u32);
        }
        for k in 0..ns {
            assert_eq!(a.surface_nodes[b * ns + k], t.surface.nodes[k] + off);
            // Control areas scale with scale^2 (1e-12 relative).
            assert_relative_eq!(
                a.control_areas[b * ns + k],
                p.scale * p.scale * t.surface.control_areas[k],
                max_relative = 1e-12
            );
        }
        // Volume = scale^3 x template volume (1e-12 relative: rotation is orthogonal to
        // round-off, the rest is exact scaling).
        assert_relative_eq!(
            body_volume(&a, b),
            p.scale.powi(3) * tv,
            max_relative = 1e-12
        );
        // Rotation preserves edge lengths: every element edge is scale x its template edge.
        for e in 0..ne {
            let g = a.element(b * ne + e).unwrap();
            let l = t.element(e);
            for (i, j) in [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)] {
                let lg = distance(a.nodes[g[i]], a.nodes[g[j]]);
                let lt = distance(t.nodes[l[i]], t.nodes[l[j]]);
                assert_relative_eq!(lg, p.scale * lt, max_relative = 1e-12);
            }
        }
        // The centre goes to the translation.
        let centre = a.element(b * ne).unwrap()[0];
        for k in 0..3 {
            assert!((a.nodes[centre][k] - p.translation[k]).abs() < 1e-15);
        }
    }
    // Quality of the template is not changed by placing it.
    assert_eq!(t.quality(), tq);
}

#[test]
fn bad_placements_are_rejected_and_add_nothing() {
    let t = template(0, ElementOrder::Linear);
    let mut a = MeshAssembly::new();
    let bad = [
        Placement {
            rotation: [1.0, 0.1, 0.0, 0.0], // norm 1.005
            ..Placement::identity()
        },
        Placement {
            rotation: [0.0; 4],
            ..Placement::identity()
        },
        Placement {
            rotation: [f64::NAN, 0.0, 0.0, 0.0],
            ..Placement::identity()
        },
        Placement {
            rotation: [f64::INFINITY, 0.0, 0.0, 0.0],
            ..Placement::identity()
        },
    ];
    for p in &bad {
        let err = a.push_instance(&t, p).unwrap_err();
        assert!(matches!(err, MeshError::InvalidRotation { .. }), "{p:?}");
        assert!(err.to_string().contains("unit quaternion"));
    }
    for scale in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let p = Placement {
            scale,
            ..Placement::identity()
        };
        assert!(matches!(
            a.push_instance(&t, &p),
            Err(MeshError::InvalidScale { .. })
        ));
    }
    assert!(matches!(
        a.push_instance(&t, &Placement::at([0.0, f64::NAN, 0.0])),
        Err(MeshError::InvalidTranslation { .. })
    ));
    assert_eq!(a, MeshAssembly::new());

    // Within the 1e-6 tolerance the quaternion is accepted (and renormalised).
    let p = Placement {
        rotation: [1.0 + 5e-7, 0.0, 0.0, 0.0],
        ..Placement::identity()
    };
    a.push_instance(&t, &p).unwrap();
    assert_relative_eq!(body_volume(&a, 0), t.volume(), max_relative = 1e-12);
}

#[test]
fn mixed_orders_and_broken_templates_are_rejected() {
    let mut a = MeshAssembly::new();
    a.push_instance(&template(0, ElementOrder::Linear), &Placement::identity())
        .unwrap();
    let err = a
        .push_instance(
            &template(0, ElementOrder::Quadratic),
            &Placement::identity(),
        )
        .unwrap_err();
    assert!(matches!(err, MeshError::MixedOrder { .. }));
    assert!(err.to_string().contains("same order"));
    assert_eq!(a.n_bodies(), 1);

    let mut broken = template(0, ElementOrder::Linear);
    broken.elements[5] = 1000;
    let err = a
        .push_instance(&broken, &Placement::identity())
        .unwrap_err();
    assert!(matches!(err, MeshError::InvalidMesh { .. }));
    assert!(
        err.to_string().contains("element 1 refers to node 1000"),
        "{err}"
    );
    assert_eq!(a.n_bodies(), 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any rotation, scale and translation keeps volume = scale^3 V and every edge = scale
    /// times its template length. Tolerance: 1e-12 relative, plus the round-off of
    /// coordinates of magnitude |t| (a few ulps of |t|) when differences are taken.
    #[test]
    fn placement_is_a_similarity(
        axis in prop::array::uniform3(-1.0f64..1.0).prop_filter("non-zero axis",
            |v| v.iter().map(|c| c * c).sum::<f64>() > 1e-3),
        angle in -6.3f64..6.3,
        scale in 0.1f64..10.0,
        translation in prop::array::uniform3(-10.0f64..10.0),
    ) {
        let t = template(0, ElementOrder::Quadratic);
        let p = Placement { scale, rotation: axis_angle(axis, angle), translation };
        let mut a = MeshAssembly::new();
        a.push_instance(&t, &p).unwrap();
        let reach = translation.iter().fold(0.0f64, |m, c| m.max(c.abs())) + scale * 0.015;
        let coordinate_roundoff = 8.0 * f64::EPSILON * reach;
        let min_edge = scale * t.quality().min_edge;
        let v = body_volume(&a, 0);
        let v_tol = 1e-12 + 3.0 * coordinate_roundoff / min_edge;
        prop_assert!((v / (scale.powi(3) * t.volume()) - 1.0).abs() < v_tol);
        for e in 0..t.n_elements() {
            let l = t.element(e);
            for (i, j) in [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)] {
                let lg = distance(a.nodes[l[i]], a.nodes[l[j]]);
                let lt = distance(t.nodes[l[i]], t.nodes[l[j]]);
                prop_assert!((lg - scale * lt).abs() < 1e-12 * scale * lt + coordinate_roundoff);
            }
        }
    }
}
