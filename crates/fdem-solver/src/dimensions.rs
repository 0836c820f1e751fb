//! Every physical field of the scene schema with its dimension, declared once.
//!
//! [`Scene::visit_fields`] walks all numeric fields of a scene and hands each to a visitor
//! with its key path, its dimension (from `fdem-scaling`'s catalogue) and its role in
//! coarse graining. Scaling a scene ([`Scene::scaled`]) and coarse graining it
//! ([`Scene::coarsened`]) are generic over this walk: there is no hand-written list of
//! multiplications anywhere. Each section is destructured without `..`, so adding a field
//! to a section does not compile until it is declared here. The sections that other
//! schemas reuse (`[material]`, `[contact]`) expose their own walk
//! ([`MaterialSection::visit_fields`], [`ContactSection::visit_fields`]), and
//! [`Role::coarse_graining_factor`] is the one rule of coarse graining, so a schema that
//! embeds them scales them without listing their fields again.

use crate::scene::{
    ContactSection, MaterialSection, ParticleSection, Scene, SimulationSection, WallSection,
};
use fdem_scaling::{Dimension, ScaleLaw, dimension_of};

/// A factor applied to one field: `(key path, catalogue quantity, factor)`.
pub type Applied = (String, &'static str, f64);

/// How a field behaves when particles are coarse-grained in a fixed domain (docs/MODEL.md
/// section 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Domain, loading and time: kept in coarse graining (positions, walls, durations,
    /// velocities, gravity, the time step).
    Domain,
    /// Particle size: multiplied by h in coarse graining (diameters, the contact margin).
    Particle,
    /// Material and contact parameters: kept in plain coarse graining, scaled by their
    /// Table 1 factor with exact scaling (only the penalty changes, by 1/h).
    Parameter,
}

impl Role {
    /// The factor of a field of this role and `dimension` in coarse graining by the `h`
    /// of `law` (`ScaleLaw::exact(h)`, docs/MODEL.md section 5): particle sizes take their
    /// factor; material and contact parameters take theirs only with `exact_scaling`;
    /// domain, loads and times keep 1.
    pub fn coarse_graining_factor(
        self,
        law: &ScaleLaw,
        dimension: Dimension,
        exact_scaling: bool,
    ) -> f64 {
        match self {
            Role::Particle => law.factor(dimension),
            Role::Parameter if exact_scaling => law.factor(dimension),
            Role::Parameter | Role::Domain => 1.0,
        }
    }
}

/// One numeric field: where it is, what it is, and its value to read or change.
pub struct Field<'a> {
    /// Key path as in error messages, e.g. `particle[2].center[0]`.
    pub key: String,
    /// Catalogue quantity name (`length`, `time_step`, ...).
    pub quantity: &'static str,
    /// Its dimension.
    pub dimension: Dimension,
    /// Its role in coarse graining.
    pub role: Role,
    /// The value.
    pub value: &'a mut f64,
}

impl<'a> Field<'a> {
    /// The field `key` holding a catalogued `quantity` (its dimension from the catalogue)
    /// with `role`: for schemas that declare fields of their own next to the sections
    /// walked here.
    pub fn new(key: String, quantity: &'static str, role: Role, value: &'a mut f64) -> Self {
        // Every quantity named is in the catalogue (checked by the tests of this module for
        // the scene's fields); an unknown name would be a programming error caught there.
        let dimension = dimension_of(quantity).unwrap_or(Dimension::NONE);
        Field {
            key,
            quantity,
            dimension,
            role,
            value,
        }
    }
}

/// Walks fields, stamping quantity and role.
struct Walker<'v, 'f> {
    visit: &'v mut dyn FnMut(Field<'_>),
    prefix: String,
    _marker: std::marker::PhantomData<&'f ()>,
}

impl<'v> Walker<'v, '_> {
    fn new(visit: &'v mut dyn FnMut(Field<'_>), prefix: &str) -> Self {
        Walker {
            visit,
            prefix: prefix.to_string(),
            _marker: std::marker::PhantomData,
        }
    }

    fn scalar(&mut self, key: &str, quantity: &'static str, role: Role, value: &mut f64) {
        let key = format!("{}{key}", self.prefix);
        (self.visit)(Field::new(key, quantity, role, value));
    }

    fn opt(&mut self, key: &str, quantity: &'static str, role: Role, value: &mut Option<f64>) {
        if let Some(v) = value.as_mut() {
            self.scalar(key, quantity, role, v);
        }
    }

    fn array<const N: usize>(
        &mut self,
        key: &str,
        quantity: &'static str,
        role: Role,
        value: &mut [f64; N],
    ) {
        for (i, v) in value.iter_mut().enumerate() {
            self.scalar(&format!("{key}[{i}]"), quantity, role, v);
        }
    }

    fn opt_array<const N: usize>(
        &mut self,
        key: &str,
        quantity: &'static str,
        role: Role,
        value: &mut Option<[f64; N]>,
    ) {
        if let Some(v) = value.as_mut() {
            self.array(key, quantity, role, v);
        }
    }
}

impl Scene {
    /// A copy with every defaulted physical parameter written out (the `[contact]` table),
    /// so that a transform scales it too: a default the file does not state would
    /// otherwise silently keep its unscaled value.
    pub fn with_explicit_defaults(&self) -> Scene {
        let mut out = self.clone();
        out.contact = Some(self.contact_section());
        out
    }

    /// Calls `visit` for every numeric field present in the scene, with its dimension.
    pub fn visit_fields(&mut self, visit: &mut dyn FnMut(Field<'_>)) {
        let Scene {
            simulation,
            material,
            particles,
            contact,
            walls,
            auto,
        } = self;
        let mut w = Walker::new(visit, "");
        w.prefix = "simulation.".into();
        simulation_fields(&mut w, simulation);
        w.prefix = "material.".into();
        material_fields(&mut w, material);
        for (i, p) in particles.iter_mut().enumerate() {
            w.prefix = format!("particle[{i}].");
            particle_fields(&mut w, p);
        }
        if let Some(c) = contact.as_mut() {
            w.prefix = "contact.".into();
            contact_fields(&mut w, c);
        }
        for (i, wall) in walls.iter_mut().enumerate() {
            w.prefix = format!("wall[{i}].");
            wall_fields(&mut w, wall);
        }
        if let Some(a) = auto.as_mut() {
            w.prefix = "auto.".into();
            // At a fixed stress the contact force grows with the particle's area.
            w.scalar(
                "contact_force",
                "force",
                Role::Particle,
                &mut a.contact_force,
            );
            w.scalar("threshold", "ratio", Role::Domain, &mut a.threshold);
        }
    }

    /// The scene scaled by `law`: every field times `law.factor(its dimension)`.
    ///
    /// With `ScaleLaw::exact(h)` this is the exactly scaled system of docs/MODEL.md section 4:
    /// lengths x h, times and the time step x h, penalty / h, gravity / h, angular
    /// velocities / h, densities, moduli, velocities and dimensionless numbers unchanged.
    /// Returns the scaled scene and, per field, `(key, quantity, factor)`.
    pub fn scaled(&self, law: &ScaleLaw) -> (Scene, Vec<Applied>) {
        let mut out = self.with_explicit_defaults();
        let mut applied = Vec::new();
        out.visit_fields(&mut |f: Field<'_>| {
            let factor = law.factor(f.dimension);
            *f.value *= factor;
            applied.push((f.key, f.quantity, factor));
        });
        (out, applied)
    }

    /// Coarse graining by `h` in the same domain (docs/MODEL.md section 5): particle sizes x h;
    /// domain, loads, velocities and times unchanged; with `exact_scaling` the material and
    /// contact parameters follow Table 1 (`ScaleLaw::exact(h)`), which changes only the
    /// penalty (/ h). Particle positions are kept: where coarse particles go is the specimen
    /// generator's job. Returns the scene and, per changed field, `(key, quantity, factor)`.
    pub fn coarsened(
        &self,
        h: f64,
        exact_scaling: bool,
    ) -> Result<(Scene, Vec<Applied>), fdem_scaling::ScalingError> {
        let law = ScaleLaw::exact(h)?;
        let mut out = self.with_explicit_defaults();
        let mut applied = Vec::new();
        out.visit_fields(&mut |f: Field<'_>| {
            let factor = f
                .role
                .coarse_graining_factor(&law, f.dimension, exact_scaling);
            if factor != 1.0 {
                *f.value *= factor;
                applied.push((f.key, f.quantity, factor));
            }
        });
        Ok((out, applied))
    }
}

impl MaterialSection {
    /// Calls `visit` for every numeric field of the section, keys prefixed by `prefix`
    /// (`material.` in a scene).
    pub fn visit_fields(&mut self, prefix: &str, visit: &mut dyn FnMut(Field<'_>)) {
        material_fields(&mut Walker::new(visit, prefix), self);
    }
}

impl ContactSection {
    /// Calls `visit` for every numeric field present in the section, keys prefixed by
    /// `prefix` (`contact.` in a scene).
    pub fn visit_fields(&mut self, prefix: &str, visit: &mut dyn FnMut(Field<'_>)) {
        contact_fields(&mut Walker::new(visit, prefix), self);
    }
}

fn simulation_fields(w: &mut Walker<'_, '_>, s: &mut SimulationSection) {
    let SimulationSection {
        duration,
        dt,
        dt_safety,
        output_interval,
        gravity,
        energy_tolerance,
        allow_initial_overlap: _, // a switch, not a quantity
    } = s;
    w.scalar("duration", "time", Role::Domain, duration);
    w.opt("dt", "time_step", Role::Domain, dt);
    w.opt("dt_safety", "ratio", Role::Domain, dt_safety);
    w.opt("output_interval", "time", Role::Domain, output_interval);
    w.opt_array("gravity", "acceleration", Role::Domain, gravity);
    w.opt("energy_tolerance", "ratio", Role::Domain, energy_tolerance);
}

fn material_fields(w: &mut Walker<'_, '_>, m: &mut MaterialSection) {
    let MaterialSection {
        density,
        youngs_modulus,
        poisson_ratio,
    } = m;
    w.scalar("density", "density", Role::Parameter, density);
    w.scalar(
        "youngs_modulus",
        "youngs_modulus",
        Role::Parameter,
        youngs_modulus,
    );
    w.scalar(
        "poisson_ratio",
        "poisson_ratio",
        Role::Parameter,
        poisson_ratio,
    );
}

fn particle_fields(w: &mut Walker<'_, '_>, p: &mut ParticleSection) {
    let ParticleSection {
        diameter,
        center,
        velocity,
        angular_velocity,
        orientation,
        mesh: _,  // level, order, sizing and relative axes are not physical quantities
        model: _, // a choice of model, not a quantity
    } = p;
    w.scalar("diameter", "length", Role::Particle, diameter);
    w.array("center", "length", Role::Domain, center);
    w.opt_array("velocity", "velocity", Role::Domain, velocity);
    w.opt_array(
        "angular_velocity",
        "angular_velocity",
        Role::Domain,
        angular_velocity,
    );
    w.opt_array("orientation", "ratio", Role::Domain, orientation);
}

fn contact_fields(w: &mut Walker<'_, '_>, c: &mut ContactSection) {
    let ContactSection {
        enabled: _, // a switch, not a quantity
        normal_penalty,
        penalty_ratio,
        friction,
        damping,
        damping_ratio,
        margin,
        depth_limit,
    } = c;
    w.scalar(
        "normal_penalty",
        "penalty_stiffness",
        Role::Parameter,
        normal_penalty,
    );
    w.scalar("penalty_ratio", "ratio", Role::Parameter, penalty_ratio);
    w.scalar("friction", "friction", Role::Parameter, friction);
    w.scalar("damping", "damping", Role::Parameter, damping);
    w.scalar("damping_ratio", "damping", Role::Parameter, damping_ratio);
    w.opt("margin", "length", Role::Particle, margin);
    w.opt("depth_limit", "length", Role::Particle, depth_limit);
}

fn wall_fields(w: &mut Walker<'_, '_>, wall: &mut WallSection) {
    let WallSection {
        kind: _, // plane or cylinder
        point,
        normal,
        axis_point,
        axis,
        radius,
        velocity,
    } = wall;
    w.opt_array("point", "length", Role::Domain, point);
    w.opt_array("normal", "ratio", Role::Domain, normal);
    w.opt_array("axis_point", "length", Role::Domain, axis_point);
    w.opt_array("axis", "ratio", Role::Domain, axis);
    w.opt("radius", "length", Role::Domain, radius);
    w.opt_array("velocity", "velocity", Role::Domain, velocity);
}

#[cfg(test)]
mod tests {
    use super::*;

    const EVERY_KEY: &str = r#"
[simulation]
duration = 1.0e-3
dt = 1.0e-7
dt_safety = 0.5
output_interval = 1.0e-5
gravity = [0.0, 0.0, -9.81]
energy_tolerance = 0.05
[material]
density = 2650.0
youngs_modulus = 40.0e9
poisson_ratio = 0.2
[contact]
enabled = true
normal_penalty = 1.8e11
penalty_ratio = 1.0
friction = 0.3
damping = 0.2
damping_ratio = 1.0
margin = 1.0e-3
[[wall]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
velocity = [0.0, 0.0, 0.1]
[[wall]]
type = "cylinder"
axis_point = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
radius = 0.1
[[particle]]
diameter = 0.015
center = [0.0, 0.0, 0.0]
velocity = [0.5, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 100.0]
orientation = [1.0, 0.0, 0.0, 0.0]
mesh = { level = 1, order = "linear", sizing = "inscribed" }
"#;

    /// Every float in the serialized scene (all optional keys present) is visited exactly
    /// once with a catalogued quantity: a field added to the schema without a dimension
    /// fails here (and does not compile in the destructuring above).
    #[test]
    fn every_numeric_field_declares_a_catalogued_dimension() {
        let mut scene = Scene::from_toml_str(EVERY_KEY, "test").unwrap();
        let mut visited = Vec::new();
        scene.visit_fields(&mut |f: Field<'_>| {
            assert!(
                fdem_scaling::quantity(f.quantity).is_some(),
                "{} declares unknown quantity {}",
                f.key,
                f.quantity
            );
            visited.push(f.key);
        });
        let value: toml::Value = toml::from_str(&scene.to_toml_string().unwrap()).unwrap();
        let mut floats = Vec::new();
        collect_floats(&value, String::new(), &mut floats);
        visited.sort();
        floats.sort();
        assert_eq!(visited, floats);
    }

    /// The walks of `[material]` and `[contact]` alone are the scene walk's entries of
    /// those sections, and the coarse-graining rule gives the factors of `coarsened`.
    #[test]
    fn section_walks_are_the_scene_walk() {
        let mut scene = Scene::from_toml_str(EVERY_KEY, "test").unwrap();
        let mut whole = Vec::new();
        scene.visit_fields(&mut |f: Field<'_>| whole.push((f.key, f.quantity, f.role)));
        whole.retain(|(k, _, _)| k.starts_with("material.") || k.starts_with("contact."));
        let mut sections = Vec::new();
        let mut record = |f: Field<'_>| sections.push((f.key, f.quantity, f.role));
        scene.material.visit_fields("material.", &mut record);
        let contact = scene.contact.as_mut().unwrap();
        contact.visit_fields("contact.", &mut record);
        assert_eq!(sections, whole);
        let law = ScaleLaw::exact(2.0).unwrap();
        let penalty = dimension_of("penalty_stiffness").unwrap();
        let length = dimension_of("length").unwrap();
        assert_eq!(
            Role::Parameter.coarse_graining_factor(&law, penalty, true),
            0.5
        );
        assert_eq!(
            Role::Parameter.coarse_graining_factor(&law, penalty, false),
            1.0
        );
        assert_eq!(
            Role::Particle.coarse_graining_factor(&law, length, false),
            2.0
        );
        assert_eq!(Role::Domain.coarse_graining_factor(&law, length, true), 1.0);
    }

    fn collect_floats(v: &toml::Value, path: String, out: &mut Vec<String>) {
        let join = |p: &str, k: &str| {
            if p.is_empty() {
                k.to_string()
            } else {
                format!("{p}.{k}")
            }
        };
        match v {
            toml::Value::Float(_) => out.push(path),
            toml::Value::Table(t) => {
                for (k, x) in t {
                    if k == "mesh" {
                        continue; // integers, names and dimensionless axes
                    }
                    // Arrays of tables are named like `particle[0]` in key paths.
                    if let toml::Value::Array(items) = x
                        && items.iter().all(|i| i.is_table())
                        && !items.is_empty()
                    {
                        for (i, item) in items.iter().enumerate() {
                            collect_floats(item, join(&path, &format!("{k}[{i}]")), out);
                        }
                        continue;
                    }
                    collect_floats(x, join(&path, k), out);
                }
            }
            toml::Value::Array(items) => {
                for (i, item) in items.iter().enumerate() {
                    collect_floats(item, format!("{path}[{i}]"), out);
                }
            }
            _ => {}
        }
    }

    #[test]
    fn exact_scaling_multiplies_by_table_1() {
        let scene = Scene::from_toml_str(EVERY_KEY, "test").unwrap();
        let h = 4.0;
        let (scaled, applied) = scene.scaled(&ScaleLaw::exact(h).unwrap());
        assert_eq!(scaled.simulation.duration, scene.simulation.duration * h);
        assert_eq!(scaled.simulation.dt, scene.simulation.dt.map(|t| t * h));
        assert_eq!(scaled.particles[0].diameter, 0.015 * h);
        assert_eq!(scaled.particles[0].velocity, Some([0.5, 0.0, 0.0]));
        assert_eq!(scaled.particles[0].angular_velocity, Some([0.0, 0.0, 25.0]));
        assert_eq!(scaled.simulation.gravity, Some([0.0, 0.0, -9.81 / 4.0]));
        let contact = scaled.contact.unwrap();
        assert_eq!(contact.normal_penalty, 1.8e11 / 4.0);
        assert_eq!(contact.friction, 0.3);
        assert_eq!(scaled.material, scene.material);
        assert_eq!(scaled.walls[1].radius, Some(0.4));
        assert!(applied.iter().any(|(k, q, f)| k == "contact.normal_penalty"
            && *q == "penalty_stiffness"
            && *f == 0.25));
    }

    #[test]
    fn coarse_graining_changes_sizes_and_with_exact_scaling_the_penalty() {
        let scene = Scene::from_toml_str(EVERY_KEY, "test").unwrap();
        let (plain, changed) = scene.coarsened(2.0, false).unwrap();
        assert_eq!(plain.particles[0].diameter, 0.03);
        assert_eq!(plain.contact.as_ref().unwrap().normal_penalty, 1.8e11);
        assert_eq!(plain.particles[0].center, scene.particles[0].center);
        assert_eq!(plain.simulation, scene.simulation);
        let keys: Vec<&str> = changed.iter().map(|c| c.0.as_str()).collect();
        assert_eq!(keys, ["particle[0].diameter", "contact.margin"]);
        let (exact, changed) = scene.coarsened(2.0, true).unwrap();
        assert_eq!(exact.contact.as_ref().unwrap().normal_penalty, 0.9e11);
        assert_eq!(exact.material, scene.material);
        assert_eq!(changed.len(), 3);
    }
}
