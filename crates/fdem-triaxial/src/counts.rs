//! The count rule (docs/MODEL.md section 7): how many particles of each size a specimen holds,
//! and the elements and nodes of their meshes.

use crate::spec::DEFAULT_SOLID_FRACTION;
use crate::{SpecimenSpec, TriaxialError};
use fdem_core::number::Number;
use fdem_mesh::{SphereSpec, sphere_mesh};
use fdem_solver::{
    DEFAULT_AUTO_THRESHOLD, DeflectionEstimate, DeflectionInputs, ParticleModel,
    deflection_estimate, mean_contact_force, mean_node_area,
};

/// Contacts per particle assumed by the `auto` model's expected contact force: the low
/// end of a packing's coordination, so that the force is not underestimated.
pub const AUTO_COORDINATION: f64 = 4.0;
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
    /// The class's particle model (`auto` resolved: deformable or rigid).
    pub model: ParticleModel,
    /// Tetrahedra per particle (0 for a rigid one).
    pub elements_per_particle: u64,
    /// Simulated nodes per particle (a rigid one's surface nodes).
    pub nodes_per_particle: u64,
    /// The estimate behind an `auto` decision.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto: Option<DeflectionEstimate>,
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
    /// Rigid particles.
    pub rigid_particles: u64,
    /// Surface (contact) nodes of all particles.
    pub surface_nodes: u64,
    /// Per size class, in the order of the gradation.
    pub classes: Vec<ClassCount>,
    /// Nominal solid volume `sum n_i pi d_i^3 / 6` (m^3).
    pub solid_volume: f64,
    /// Nominal solid fraction: solid volume over the inner volume at the target height.
    pub solid_fraction: f64,
}

impl Counts {
    /// Estimated peak memory of a preparation or test of these counts (bytes): node
    /// state, elements, contact data per surface node and a fixed base, by the rule
    /// scenes use too ([`fdem_solver::ModelSize::bytes`]; docs/PERFORMANCE.md, "Memory").
    pub fn memory_estimate(&self, quadratic: bool) -> u64 {
        let (linear_elements, quadratic_elements) = if quadratic {
            (0, self.elements)
        } else {
            (self.elements, 0)
        };
        fdem_solver::ModelSize {
            particles: self.particles,
            nodes: self.nodes,
            linear_elements,
            quadratic_elements,
            contact_nodes: self.surface_nodes,
            rigid_triangles: 0,
        }
        .bytes()
    }

    /// One line per size class: its model and what it simulates per particle, and for
    /// an `auto` decision the estimate behind it.
    pub fn model_report(&self) -> Vec<String> {
        self.classes
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let mut line = format!(
                    "class {i} (d = {:e} m, {} particles): {}, {} elements and {} nodes per particle",
                    c.diameter,
                    c.particles,
                    c.model.name(),
                    c.elements_per_particle,
                    c.nodes_per_particle
                );
                if let Some(e) = &c.auto {
                    line.push_str(&format!("; auto: {e}"));
                }
                line
            })
            .collect()
    }

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
                    Number(c.mass_fraction),
                    Number(c.size),
                    Number(c.size * h)
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
        let h = self.coarse_graining;
        let diameters: Vec<f64> = self.gradation.iter().map(|c| c.size * h).collect();
        let solid_volume: f64 = diameters
            .iter()
            .zip(&per_class)
            .map(|(&d, &n)| n as f64 * sphere_volume(d))
            .sum();
        let solid_fraction = solid_volume / self.inner_volume();
        // A rigid particle simulates no elements and only its surface nodes.
        let deformable = (template.n_elements() as u64, template.n_nodes() as u64);
        let surface_per_particle = surface_node_count(&template).map_err(mesh_error)? as u64;
        let rigid = (0, surface_per_particle);
        let mut classes = Vec::with_capacity(per_class.len());
        for ((c, &n), &d) in self.gradation.iter().zip(&per_class).zip(&diameters) {
            let auto = match self.model {
                ParticleModel::Auto => Some(self.auto_estimate(d, solid_fraction, &template)?),
                _ => None,
            };
            let model = auto.map_or(self.model, |e| e.model);
            let (epp, npp) = if model == ParticleModel::Rigid {
                rigid
            } else {
                deformable
            };
            classes.push(ClassCount {
                diameter: d,
                mass_fraction: c.mass_fraction,
                particles: n,
                model,
                elements_per_particle: epp,
                nodes_per_particle: npp,
                auto,
            });
        }
        let particles: u64 = per_class.iter().sum();
        let total = |f: fn(&ClassCount) -> u64| classes.iter().map(|c| c.particles * f(c)).sum();
        let (elements, nodes) = (
            total(|c| c.elements_per_particle),
            total(|c| c.nodes_per_particle),
        );
        let rigid_particles = classes
            .iter()
            .filter(|c| c.model == ParticleModel::Rigid)
            .map(|c| c.particles)
            .sum();
        Ok(Counts {
            particles,
            elements,
            nodes,
            rigid_particles,
            surface_nodes: particles.saturating_mul(surface_per_particle),
            classes,
            solid_volume,
            solid_fraction,
        })
    }

    /// The `auto` decision for the particles of simulated diameter `d` in a packing of
    /// nominal solid fraction `phi` under the confining pressure: the expected contact
    /// force from Love-Weber with [`AUTO_COORDINATION`] contacts per particle, the
    /// simulated material and penalty, the mesh's mean surface-node control area.
    fn auto_estimate(
        &self,
        d: f64,
        phi: f64,
        template: &fdem_mesh::TetMesh,
    ) -> Result<DeflectionEstimate, TriaxialError> {
        let simulated = self.simulated()?;
        let force = mean_contact_force(self.confining_pressure, d, phi, AUTO_COORDINATION);
        Ok(deflection_estimate(
            DeflectionInputs {
                diameter: d,
                youngs_modulus: simulated.material.youngs_modulus,
                poisson_ratio: simulated.material.poisson_ratio,
                normal_penalty: simulated.contact.normal_penalty,
                node_area: mean_node_area(template, d),
                contact_force: force,
            },
            self.auto_threshold.unwrap_or(DEFAULT_AUTO_THRESHOLD),
        ))
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
