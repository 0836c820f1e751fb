//! Impossible starting geometry: particles placed deep inside one another, across a wall
//! or behind it. The narrow phase looks only `depth_limit` behind a face, so such a
//! start would run without contact between the parts that overlap (or stop later with a
//! misleading cause); it is refused before the run, naming the bodies.

use crate::SolverError;
use crate::scene::{ParticleSection, WallSection, WallType};
use fdem_core::geometry::{distance, dot, norm, scale, sub, triangle_area_vector};
use fdem_mesh::TetMesh;

/// The radius of the largest ball about the template's centre (the origin) inside its
/// surface, for a unit diameter: the smallest distance from the centre to a face plane.
/// A convex mesh (the sphere and ellipsoid templates) contains that ball, so two balls
/// that overlap by `d` mean meshes that overlap by at least `d`.
pub fn inscribed_radius(template: &TetMesh) -> f64 {
    let x = &template.nodes;
    template
        .surface
        .triangles
        .iter()
        .map(|&[a, b, c]| {
            let n = triangle_area_vector(x[a], x[b], x[c]);
            (dot(n, x[a]) / norm(n)).abs()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Refuses a start where two particles' inscribed balls overlap by more than `limit`, or
/// a particle's inscribed ball reaches more than `limit` across a wall (or its centre lies
/// behind one). `radii[i]` is particle `i`'s inscribed radius (m); `limit` the deepest
/// contact the run accepts (half the depth limit).
pub fn check(
    particles: &[ParticleSection],
    radii: &[f64],
    walls: &[WallSection],
    limit: f64,
) -> Result<(), SolverError> {
    let fix = "move them apart, or set simulation.allow_initial_overlap = true to start so";
    // Sweep along x: a pair can overlap only where their x ranges do.
    let mut order: Vec<usize> = (0..particles.len()).collect();
    let left = |i: usize| particles[i].center[0] - radii[i];
    order.sort_by(|&a, &b| left(a).total_cmp(&left(b)));
    for (k, &i) in order.iter().enumerate() {
        let right = particles[i].center[0] + radii[i];
        for &j in order[k + 1..].iter().take_while(|&&j| left(j) <= right) {
            let dist = distance(particles[i].center, particles[j].center);
            let overlap = radii[i] + radii[j] - dist;
            if overlap > limit {
                let (i, j) = (i.min(j), i.max(j));
                return Err(SolverError::InvalidScene(format!(
                    "particle[{i}] and particle[{j}] start {overlap:.3e} m inside each other \
                     (centres {dist:.3e} m apart), deeper than the {limit:.3e} m a contact may \
                     reach; {fix}"
                )));
            }
        }
    }
    for (w, wall) in walls.iter().enumerate() {
        for (i, p) in particles.iter().enumerate() {
            let Some(inside) = inside_distance(wall, p.center) else {
                continue;
            };
            if inside < 0.0 {
                return Err(SolverError::InvalidScene(format!(
                    "particle[{i}] lies behind wall[{w}] (its centre {:.3e} m on the far side); {fix}",
                    -inside
                )));
            }
            if radii[i] - inside > limit {
                return Err(SolverError::InvalidScene(format!(
                    "particle[{i}] is cut by wall[{w}] ({:.3e} m of it across the wall, deeper \
                     than the {limit:.3e} m a contact may reach); {fix}",
                    radii[i] - inside
                )));
            }
        }
    }
    Ok(())
}

/// Signed distance of `x` from `wall` towards the particles' side (negative behind it);
/// `None` for a wall without its keys (refused elsewhere).
fn inside_distance(wall: &WallSection, x: [f64; 3]) -> Option<f64> {
    let unit = |v: [f64; 3]| {
        let n = norm(v);
        (n > 0.0).then(|| scale(v, 1.0 / n))
    };
    match wall.kind {
        WallType::Plane => {
            let (p, n) = (wall.point?, unit(wall.normal?)?);
            Some(dot(sub(x, p), n))
        }
        WallType::Cylinder => {
            let (p, a, r) = (wall.axis_point?, unit(wall.axis?)?, wall.radius?);
            let d = sub(x, p);
            Some(r - norm(sub(d, scale(a, dot(d, a)))))
        }
    }
}
