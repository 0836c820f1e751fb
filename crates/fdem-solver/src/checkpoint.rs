//! The state a simulation carries from one step to the next, taken between steps and
//! restored into a simulation built from the same model, so that a run resumed from it
//! continues bit for bit ([`crate::Simulation::checkpoint`],
//! [`crate::Simulation::restore_checkpoint`]).
//!
//! Velocity Verlet starts a step from the positions, the velocities and the forces of
//! the last evaluation (its first half kick uses them); rigid bodies from their pose,
//! momenta, force and torque; contact from its tangential history, walls and wall forces;
//! the energy balance from its running sums; a contribution from whatever it keeps
//! between evaluations ([`crate::ForceContribution::checkpoint`]). What is rebuilt on
//! demand (the contact broad phase, scratch buffers) and what the model's definition
//! fixes (masses, references, elements) is not part of it.

use crate::SolverError;
use crate::rigid::RigidState;
use fdem_contact::{ContactCheckpoint, Counterpart, Wall, WallShape};
use fdem_core::sections::Sections;

/// Numbers per rigid body: pose and momenta (13), gravity's reference centre (3), force
/// (3) and torque (3) of the last evaluation.
const RIGID_NUMBERS: usize = 22;
/// Numbers per history entry: node, counterpart code, tangential displacement (3).
const HISTORY_NUMBERS: usize = 5;
/// Numbers per wall: kind, two points or vectors (6), radius, velocity (3).
const WALL_NUMBERS: usize = 11;

/// A rigid body's part of a checkpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidCheckpoint {
    /// Pose and momenta.
    pub state: RigidState,
    /// Centre of mass at the reference of gravity's work (m).
    pub reference: [f64; 3],
    /// Force of the last evaluation (N).
    pub force: [f64; 3],
    /// Torque about the centre of the last evaluation (N m).
    pub torque: [f64; 3],
}

/// A simulation's state between two steps ([`crate::Simulation::checkpoint`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SimulationCheckpoint {
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// The step (s); a restore checks that the rebuilt model has the same.
    pub dt: f64,
    /// Node positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Node velocities (m/s).
    pub velocities: Vec<[f64; 3]>,
    /// Node forces of the last evaluation (N).
    pub forces: Vec<[f64; 3]>,
    /// Rigid bodies in body order.
    pub rigid: Vec<RigidCheckpoint>,
    /// The energy balance's running sums: initial energy, contributions' work, gravity's
    /// work at the reference, damping and friction dissipated (J).
    pub energy: [f64; 5],
    /// Contact's state, when the model has contact.
    pub contact: Option<ContactCheckpoint>,
    /// Each contribution's own state, in the order they were added.
    pub contributions: Vec<Vec<f64>>,
}

fn flat(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

fn triples(v: &[f64]) -> Vec<[f64; 3]> {
    v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

fn three(v: &[f64]) -> [f64; 3] {
    [v[0], v[1], v[2]]
}

impl SimulationCheckpoint {
    /// Puts the checkpoint into `out` as sections named `prefix.*`.
    pub fn to_sections(&self, prefix: &str, out: &mut Sections) {
        let name = |s: &str| format!("{prefix}.{s}");
        out.put_numbers(
            &name("clock"),
            vec![
                self.time,
                self.step as f64,
                self.dt,
                self.rigid.len() as f64,
            ],
        );
        out.put_numbers(&name("positions"), flat(&self.positions));
        out.put_numbers(&name("velocities"), flat(&self.velocities));
        out.put_numbers(&name("forces"), flat(&self.forces));
        let rigid = self.rigid.iter().flat_map(|r| {
            let s = r.state;
            [s.position, s.velocity]
                .into_iter()
                .flatten()
                .chain(s.orientation)
                .chain(s.body_momentum)
                .chain(r.reference)
                .chain(r.force)
                .chain(r.torque)
        });
        out.put_numbers(&name("rigid"), rigid.collect());
        out.put_numbers(&name("energy"), self.energy.to_vec());
        if let Some(c) = &self.contact {
            // Node ids and counterpart codes are below 2^53: exact as f64.
            let history = c.history.iter().flat_map(|&(node, counterpart, d)| {
                [node as f64, counterpart.code() as f64, d[0], d[1], d[2]]
            });
            out.put_numbers(&name("contact.history"), history.collect());
            let damping = c.damping.iter().flatten().flatten().copied();
            out.put_numbers(&name("contact.damping"), damping.collect());
            out.put_numbers(
                &name("contact.walls"),
                c.walls.iter().flat_map(wall_numbers).collect(),
            );
            out.put_numbers(&name("contact.wall_forces"), flat(&c.wall_forces));
            out.put_numbers(&name("contact.evaluations"), vec![c.evaluations as f64]);
            if let Some(d) = c.depth_limit {
                out.put_numbers(&name("contact.depth_limit"), vec![d]);
            }
        }
        out.put_numbers(
            &name("contributions"),
            self.contributions.iter().map(|c| c.len() as f64).collect(),
        );
        for (i, c) in self.contributions.iter().enumerate() {
            out.put_numbers(&name(&format!("contribution.{i}")), c.clone());
        }
    }

    /// Reads a checkpoint put by [`SimulationCheckpoint::to_sections`] with `prefix`.
    ///
    /// # Errors
    /// A message naming the section that is missing or has the wrong length.
    pub fn from_sections(prefix: &str, s: &Sections) -> Result<Self, String> {
        let name = |n: &str| format!("{prefix}.{n}");
        let clock = s.numbers_of(&name("clock"), 4)?;
        let positions = triples(s.numbers(&name("positions"))?);
        let n = positions.len();
        let velocities = triples(s.numbers_of(&name("velocities"), 3 * n)?);
        let forces = triples(s.numbers_of(&name("forces"), 3 * n)?);
        let rigid = s
            .numbers_of(&name("rigid"), RIGID_NUMBERS * clock[3] as usize)?
            .chunks_exact(RIGID_NUMBERS)
            .map(|r| RigidCheckpoint {
                state: RigidState {
                    position: three(&r[0..]),
                    velocity: three(&r[3..]),
                    orientation: [r[6], r[7], r[8], r[9]],
                    body_momentum: three(&r[10..]),
                },
                reference: three(&r[13..]),
                force: three(&r[16..]),
                torque: three(&r[19..]),
            })
            .collect();
        let energy = s.numbers_of(&name("energy"), 5)?;
        let contact = match s.numbers(&name("contact.history")) {
            Ok(h) => Some(contact_from(prefix, h, s)?),
            Err(_) => None,
        };
        let sizes = s.numbers(&name("contributions"))?;
        let contributions = sizes
            .iter()
            .enumerate()
            .map(|(i, &len)| {
                s.numbers_of(&name(&format!("contribution.{i}")), len as usize)
                    .map(<[f64]>::to_vec)
            })
            .collect::<Result<_, _>>()?;
        Ok(SimulationCheckpoint {
            time: clock[0],
            step: clock[1] as u64,
            dt: clock[2],
            positions,
            velocities,
            forces,
            rigid,
            energy: [energy[0], energy[1], energy[2], energy[3], energy[4]],
            contact,
            contributions,
        })
    }
}

fn contact_from(prefix: &str, history: &[f64], s: &Sections) -> Result<ContactCheckpoint, String> {
    let name = |n: &str| format!("{prefix}.contact.{n}");
    if !history.len().is_multiple_of(HISTORY_NUMBERS) {
        return Err(format!(
            "section `{}` is not whole entries",
            name("history")
        ));
    }
    let history = history
        .chunks_exact(HISTORY_NUMBERS)
        .map(|h| {
            let counterpart = Counterpart::from_code(h[1] as u64)
                .ok_or_else(|| format!("section `{}` holds a bad counterpart", name("history")))?;
            Ok((h[0] as usize, counterpart, three(&h[2..])))
        })
        .collect::<Result<Vec<_>, String>>()?;
    let damping = s
        .numbers_of(&name("damping"), 6 * history.len())?
        .chunks_exact(6)
        .map(|d| [three(d), three(&d[3..])])
        .collect();
    let walls = s.numbers(&name("walls"))?;
    if !walls.len().is_multiple_of(WALL_NUMBERS) {
        return Err(format!("section `{}` is not whole walls", name("walls")));
    }
    let walls: Vec<Wall> = walls.chunks_exact(WALL_NUMBERS).map(wall_from).collect();
    let wall_forces = triples(s.numbers_of(&name("wall_forces"), 3 * walls.len())?);
    let evaluations = s.numbers_of(&name("evaluations"), 1)?[0] as u64;
    // Absent from checkpoints written before the depth limit could grow.
    let depth_limit = match s.numbers(&name("depth_limit")) {
        Ok(_) => Some(s.numbers_of(&name("depth_limit"), 1)?[0]),
        Err(_) => None,
    };
    Ok(ContactCheckpoint {
        history,
        damping,
        walls,
        wall_forces,
        evaluations,
        depth_limit,
    })
}

fn wall_numbers(w: &Wall) -> [f64; WALL_NUMBERS] {
    let v = w.velocity;
    match w.shape {
        WallShape::Plane { point, normal } => [
            0.0, point[0], point[1], point[2], normal[0], normal[1], normal[2], 0.0, v[0], v[1],
            v[2],
        ],
        WallShape::Cylinder {
            axis_point: p,
            axis: a,
            radius,
        } => [
            1.0, p[0], p[1], p[2], a[0], a[1], a[2], radius, v[0], v[1], v[2],
        ],
    }
}

fn wall_from(n: &[f64]) -> Wall {
    let shape = if n[0] == 0.0 {
        WallShape::Plane {
            point: three(&n[1..]),
            normal: three(&n[4..]),
        }
    } else {
        WallShape::Cylinder {
            axis_point: three(&n[1..]),
            axis: three(&n[4..]),
            radius: n[7],
        }
    };
    Wall {
        shape,
        velocity: three(&n[8..]),
    }
}

/// The error of a checkpoint that does not fit the simulation.
pub(crate) fn mismatch(what: String) -> SolverError {
    SolverError::InvalidScene(format!(
        "the checkpoint does not fit this model: {what}; resume with the definition and \
         the build that wrote it, or start again"
    ))
}
