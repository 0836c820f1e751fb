//! The count rule (docs/MODEL.md section 7): how many particles of each size a specimen holds,
//! and the elements and nodes of their meshes.

use crate::spec::DEFAULT_SOLID_FRACTION;
use crate::{SpecimenSpec, TriaxialError};
use fdem_mesh::{SphereSpec, sphere_mesh};
use fdem_solver::ParticleModel;
use serde::{Deserialize, Serialize};

/// Nominal sphere volume `pi d^3 / 6` (m^3).
pub fn sphere_volume(diameter: f64) -> f64 {
    std::f64::consts::PI * diameter * diameter * diameter / 6.0
}

/// Particles of one size class.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassCount {
    /// Simulated diameter (m): the gradation's size times h.
    pub diameter: f64,
    /// Requested share of the solid mass.
    pub mass_fraction: f64,
    /// Number of particles.
    pub particles: u64,
}

/// Particle, element and node counts of a specimen.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Counts {
    /// Total particles.
    pub particles: u64,
    /// Total tetrahedra.
    pub elements: u64,
    /// Total nodes.
    pub nodes: u64,
    /// Tetrahedra per particle.
    pub elements_per_particle: u64,
    /// Nodes per particle.
    pub nodes_per_particle: u64,
    /// Per size class, in the order of the gradation.
    pub classes: Vec<ClassCount>,
    /// Nominal solid volume `sum n_i pi d_i^3 / 6` (m^3).
    pub solid_volume: f64,
    /// Nominal solid fraction: solid volume over the inner volume at the target height.
    pub solid_fraction: f64,
}

impl Counts {
    /// Every particle as (simulated diameter, size class), class by class: the list
    /// [`crate::place_spheres`] takes.
    pub fn diameters(&self) -> Vec<(f64, usize)> {
        self.classes
            .iter()
            .enumerate()
            .flat_map(|(i, c)| std::iter::repeat_n((c.diameter, i), c.particles as usize))
            .collect()
    }
}

/// Particles per size class (gradation order). With a solid fraction `phi`:
/// `n_i = floor(V_s f_i / (pi d_i^3 / 6))`, `V_s = phi pi r^2 H` with `r` the inner radius
/// and `d_i` the simulated diameter. With a total count `N`: `N` shared in proportion to
/// `f_i / d_i^3` by largest remainders.
///
/// Errors are `(key, message)` for [`SpecimenSpec::validate`].
pub(crate) fn class_counts(spec: &SpecimenSpec) -> Result<Vec<u64>, (String, String)> {
    let h = spec.coarse_graining;
    let volumes: Vec<f64> = spec
        .gradation
        .iter()
        .map(|c| sphere_volume(c.size * h))
        .collect();
    let total = spec.particles.filter(|_| spec.solid_fraction.is_none());
    let counts: Vec<u64> = match total {
        None => {
            let phi = spec
                .requested_solid_fraction()
                .unwrap_or(DEFAULT_SOLID_FRACTION);
            let solid = phi * spec.inner_volume();
            spec.gradation
                .iter()
                .zip(&volumes)
                .map(|(c, &v)| {
                    let n = (solid * c.mass_fraction / v).floor();
                    if n.is_finite() && n < 1e15 {
                        n as u64
                    } else {
                        u64::MAX
                    }
                })
                .collect()
        }
        Some(total) => {
            let weights: Vec<f64> = spec
                .gradation
                .iter()
                .zip(&volumes)
                .map(|(c, &v)| c.mass_fraction / v)
                .collect();
            let sum: f64 = weights.iter().sum();
            let exact: Vec<f64> = weights.iter().map(|w| total as f64 * w / sum).collect();
            let mut counts: Vec<u64> = exact.iter().map(|x| x.floor() as u64).collect();
            let mut left = total.saturating_sub(counts.iter().sum());
            // Largest remainders first; ties to the earlier class.
            let mut order: Vec<usize> = (0..exact.len()).collect();
            order.sort_by(|&a, &b| {
                let ra = exact[a] - exact[a].floor();
                let rb = exact[b] - exact[b].floor();
                rb.total_cmp(&ra).then(a.cmp(&b))
            });
            for i in order {
                if left == 0 {
                    break;
                }
                counts[i] += 1;
                left -= 1;
            }
            counts
        }
    };
    if counts.contains(&u64::MAX) {
        return Err((
            "solid_fraction".into(),
            "the particle count overflows; check the sizes".into(),
        ));
    }
    for (i, (&n, c)) in counts.iter().zip(&spec.gradation).enumerate() {
        if n == 0 {
            return Err((
                format!("gradation[{i}].mass_fraction"),
                format!(
                    "{} of the solids gives no particle of {} m (x h = {} m); raise the fraction or the specimen size, or drop the class",
                    c.mass_fraction,
                    c.size,
                    c.size * h
                ),
            ));
        }
    }
    Ok(counts)
}

impl SpecimenSpec {
    /// The counts of this specimen (validated first): particles per size class by the
    /// count rule, and elements and nodes from the mesh of one particle
    /// (`mesh.level`, `mesh.order`). Cheap: one template mesh is built.
    pub fn counts(&self) -> Result<Counts, TriaxialError> {
        self.validate(&self.name)?;
        let per_class = class_counts(self).map_err(|(key, message)| TriaxialError::Definition {
            origin: self.name.clone(),
            line: 0,
            column: 0,
            key,
            message,
        })?;
        let mesh_error = |e: fdem_mesh::MeshError| TriaxialError::Definition {
            origin: self.name.clone(),
            line: 0,
            column: 0,
            key: "mesh".into(),
            message: e.to_string(),
        };
        let template = sphere_mesh(&SphereSpec {
            level: self.mesh.level,
            order: self.mesh.order,
            diameter: 1.0,
            sizing: self.mesh.sizing,
        })
        .map_err(mesh_error)?;
        // A rigid particle simulates no elements and only its surface nodes.
        let (epp, npp) = match self.model {
            ParticleModel::Deformable => (template.n_elements() as u64, template.n_nodes() as u64),
            ParticleModel::Rigid => (0, surface_node_count(&template).map_err(mesh_error)? as u64),
        };
        let h = self.coarse_graining;
        let classes: Vec<ClassCount> = self
            .gradation
            .iter()
            .zip(&per_class)
            .map(|(c, &n)| ClassCount {
                diameter: c.size * h,
                mass_fraction: c.mass_fraction,
                particles: n,
            })
            .collect();
        let particles: u64 = per_class.iter().sum();
        let solid_volume: f64 = classes
            .iter()
            .map(|c| c.particles as f64 * sphere_volume(c.diameter))
            .sum();
        Ok(Counts {
            particles,
            elements: particles * epp,
            nodes: particles * npp,
            elements_per_particle: epp,
            nodes_per_particle: npp,
            classes,
            solid_volume,
            solid_fraction: solid_volume / self.inner_volume(),
        })
    }
}

/// Surface nodes of one instance of `template` (the nodes of a rigid particle).
fn surface_node_count(template: &fdem_mesh::TetMesh) -> Result<usize, fdem_mesh::MeshError> {
    let mut one = fdem_mesh::MeshAssembly::new();
    let placement = fdem_mesh::Placement {
        scale: 1.0,
        rotation: [1.0, 0.0, 0.0, 0.0],
        translation: [0.0; 3],
    };
    one.push_instance(template, &placement)?;
    Ok(one.surface_nodes.len())
}
