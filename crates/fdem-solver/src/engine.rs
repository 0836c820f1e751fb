//! The explicit central-difference (velocity-Verlet) engine with energy bookkeeping and
//! a stability guard.

use crate::forces::{ElasticForces, ForceContribution, NodeView, Powers, StepBound};
use crate::{Body, NodeState, SolverError};
use rayon::prelude::*;

/// Nodes per parallel task in the node-update loops.
const NODE_CHUNK: usize = 4096;

/// How the time step is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeStep {
    /// A fixed step (s), used as given even above the stable bound (the guard watches).
    Fixed(f64),
    /// `safety x` the stable bound ([`Simulation::bound`]).
    Automatic {
        /// Fraction of the bound, in (0, 1].
        safety: f64,
    },
}

/// Settings of the stability guard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Guard {
    /// The run stops when the energy balance error exceeds this fraction of the energy
    /// scale (the larger of the initial energy and the external work so far).
    pub energy_tolerance: f64,
    /// Steps between energy checks (non-finite values are checked every step).
    pub check_interval: u64,
    /// Absolute floor of the energy scale, as a fraction of `M c_p^2` (total mass times
    /// the squared p-wave speed): the kinetic energy of the system moving at
    /// `sqrt(2 x 1e-12) c_p`, about 6 mm/s for rock. Below it the balance error is
    /// round-off of a system at rest, not instability; an instability grows exponentially
    /// and passes the floor a few dozen steps after it starts.
    pub energy_floor: f64,
}

impl Default for Guard {
    fn default() -> Self {
        Guard {
            energy_tolerance: 0.05,
            check_interval: 256,
            energy_floor: 1e-12,
        }
    }
}

/// Energies at one instant (J), the columns of `energy.csv`.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EnergyReport {
    /// Simulated time (s).
    pub time: f64,
    /// Kinetic energy `sum 1/2 m v^2`.
    pub kinetic: f64,
    /// Elastic strain energy of the particles.
    pub strain: f64,
    /// Energy stored by other contributions (contact springs, ...).
    pub other_potential: f64,
    /// Energy dissipated by viscous damping since the start.
    pub damping_dissipated: f64,
    /// Energy dissipated by friction sliding since the start.
    pub friction_dissipated: f64,
    /// Work done on the system by external forces (gravity, loads) since the start.
    pub external_work: f64,
    /// Energy dissipated since the start (damping + friction).
    pub dissipated: f64,
    /// `kinetic + strain + other_potential + dissipated - external_work - initial total`:
    /// zero for exact energy conservation.
    pub balance_error: f64,
}

/// A deformable-particle system advanced by explicit central differences.
pub struct Simulation {
    /// Node state.
    pub state: NodeState,
    /// Bodies (contiguous node and element ranges).
    pub bodies: Vec<Body>,
    /// Nodes per element (4 or 10).
    pub nodes_per_element: usize,
    /// Global element connectivity, `nodes_per_element` node ids per element.
    pub connectivity: Vec<usize>,
    /// Elastic forces of the particles.
    pub elastic: ElasticForces,
    /// Further contributions (contact, walls, membranes), evaluated after the elastic one.
    pub contributions: Vec<Box<dyn ForceContribution>>,
    /// Gravitational acceleration (m/s^2), applied as `m g` on every node.
    pub gravity: [f64; 3],
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// The step size in use (s).
    pub dt: f64,
    /// The stable bound and what sets it: the elastic bound (each body's assembled bound)
    /// combined with the contact springs' ([`StepBound::combined`]), or any other
    /// contribution's bound if smaller.
    pub bound: StepBound,
    /// Stability guard settings.
    pub guard: Guard,
    initial_energy: f64,
    /// `M c_p^2` of the system (J), the unit of [`Guard::energy_floor`].
    wave_energy: f64,
    contribution_work: f64,
    damping_dissipated: f64,
    friction_dissipated: f64,
    last_powers: Powers,
}

impl Simulation {
    /// Assembles a simulation, computes the stable bound, chooses the step and evaluates
    /// the initial forces.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        state: NodeState,
        bodies: Vec<Body>,
        nodes_per_element: usize,
        connectivity: Vec<usize>,
        elastic: ElasticForces,
        contributions: Vec<Box<dyn ForceContribution>>,
        gravity: [f64; 3],
        time_step: TimeStep,
    ) -> Result<Self, SolverError> {
        // Contact springs act on the particles' surface nodes, together with the elements:
        // their bounds combine; any other contribution acts on nodes of its own.
        let contact = StepBound::smallest(
            contributions
                .iter()
                .filter(|c| c.as_contact().is_some())
                .map(|c| c.stable_time_step()),
        );
        let bound = StepBound::of_model(
            elastic.stable_time_step(),
            contact,
            contributions
                .iter()
                .filter(|c| c.as_contact().is_none())
                .map(|c| c.stable_time_step()),
        )
        .unwrap_or(StepBound {
            dt: f64::INFINITY,
            source: "nothing (no elements or contacts)".into(),
        });
        let dt = match time_step {
            TimeStep::Fixed(dt) => dt,
            TimeStep::Automatic { safety } => safety * bound.dt,
        };
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SolverError::InvalidScene(format!(
                "time step {dt:e} s is not a positive finite number (stable bound {:e} s set by {}); \
                 give simulation.dt explicitly",
                bound.dt, bound.source
            )));
        }
        let total_mass: f64 = state.masses.iter().sum();
        let wave_speed = elastic
            .bodies
            .iter()
            .map(|b| b.set.material().p_wave_speed())
            .fold(0.0, f64::max);
        let mut sim = Simulation {
            wave_energy: total_mass * wave_speed * wave_speed,
            state,
            bodies,
            nodes_per_element,
            connectivity,
            elastic,
            contributions,
            gravity,
            time: 0.0,
            step: 0,
            dt,
            bound,
            guard: Guard::default(),
            initial_energy: 0.0,
            contribution_work: 0.0,
            damping_dissipated: 0.0,
            friction_dissipated: 0.0,
            last_powers: Powers::default(),
        };
        sim.compute_forces()?;
        let e = sim.energy();
        sim.initial_energy = e.kinetic + e.strain + e.other_potential;
        Ok(sim)
    }

    /// Makes the current state the reference of the energy balance (initial energy, zero
    /// work and dissipation) and re-evaluates the forces. Call it after editing positions
    /// or velocities by hand, so that the stability guard measures from the new state.
    pub fn rebase_energy(&mut self) -> Result<(), SolverError> {
        self.compute_forces()?;
        self.contribution_work = 0.0;
        self.damping_dissipated = 0.0;
        self.friction_dissipated = 0.0;
        let e = self.energy();
        self.initial_energy = e.kinetic + e.strain + e.other_potential;
        Ok(())
    }

    /// Makes the current state the reference of the energy balance without re-evaluating
    /// the forces (they belong to the current state after [`Simulation::advance`]): the
    /// stability guard then measures from here. A driver that checks the balance over
    /// windows (the triaxial test) calls it at the end of each window.
    pub fn reset_energy_reference(&mut self) {
        self.contribution_work = 0.0;
        self.damping_dissipated = 0.0;
        self.friction_dissipated = 0.0;
        let e = self.energy();
        self.initial_energy = e.kinetic + e.strain + e.other_potential;
    }

    /// Estimates the assembled system's stable step `2 / omega_max` by power iteration on
    /// `M^-1/2 K M^-1/2`, with `K v` from the elastic forces at a tiny displacement of the
    /// reference configuration (co-rotational forces are linear to first order there).
    ///
    /// The Rayleigh quotient approaches `omega_max^2` from below, so the estimate is at or
    /// above the true bound. [`Simulation::bound`] uses each body's assembled estimate
    /// (rest stiffness, Rayleigh quotient plus residual); this whole-system check of it
    /// works from the force evaluation instead. Costs `iterations` elastic force
    /// evaluations; intended for diagnostics and tests.
    pub fn estimate_system_time_step(&mut self, iterations: usize) -> Result<f64, SolverError> {
        let n = self.state.len();
        let x0 = self.state.reference.clone();
        let size = x0
            .iter()
            .flatten()
            .fold(0.0f64, |a, &b| a.max(b.abs()))
            .max(f64::MIN_POSITIVE);
        let sqrt_inv_m: Vec<f64> = self.state.inverse_masses.iter().map(|w| w.sqrt()).collect();
        // Deterministic, non-special start vector.
        let mut y: Vec<[f64; 3]> = (0..n)
            .map(|i| [0, 1, 2].map(|k| ((i * 3 + k) as f64 * 0.618_033_988_75).fract() - 0.5))
            .collect();
        // Displacements are scaled so that the largest is 1e-7 of the model size.
        let max_sqrt_inv = sqrt_inv_m.iter().copied().fold(0.0, f64::max);
        let vscale = 1e-7 * size / max_sqrt_inv;
        let mut lambda = 0.0;
        let mut x = x0.clone();
        let mut f = vec![[0.0; 3]; n];
        for _ in 0..iterations {
            let norm = y.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
            if norm == 0.0 || !norm.is_finite() {
                break;
            }
            y.iter_mut().flatten().for_each(|v| *v /= norm);
            for i in 0..n {
                for k in 0..3 {
                    x[i][k] = x0[i][k] + vscale * sqrt_inv_m[i] * y[i][k];
                }
            }
            f.fill([0.0; 3]);
            let view = NodeView {
                positions: &x,
                velocities: &self.state.velocities,
                masses: &self.state.masses,
                time: self.time,
                dt: self.dt,
            };
            self.elastic.add_forces(view, &mut f)?;
            // A y = M^-1/2 K M^-1/2 y = -M^-1/2 f / vscale; lambda = y . A y.
            let mut dot = 0.0;
            for i in 0..n {
                for k in 0..3 {
                    let ay = -sqrt_inv_m[i] * f[i][k] / vscale;
                    dot += ay * y[i][k];
                    y[i][k] = ay;
                }
            }
            lambda = dot;
        }
        Ok(if lambda > 0.0 {
            2.0 / lambda.sqrt()
        } else {
            f64::INFINITY
        })
    }

    /// Zeroes the forces and adds every contribution and gravity for the current state.
    fn compute_forces(&mut self) -> Result<(), SolverError> {
        let state = &mut self.state;
        state
            .forces
            .par_chunks_mut(NODE_CHUNK)
            .for_each(|chunk| chunk.fill([0.0; 3]));
        let view = NodeView {
            positions: &state.positions,
            velocities: &state.velocities,
            masses: &state.masses,
            time: self.time,
            dt: self.dt,
        };
        let mut powers = self.elastic.add_forces(view, &mut state.forces)?;
        for c in &mut self.contributions {
            let p = c.add_forces(view, &mut state.forces)?;
            powers.external += p.external;
            powers.damping += p.damping;
            powers.friction_energy += p.friction_energy;
        }
        let g = self.gravity;
        if g != [0.0; 3] {
            state
                .forces
                .par_chunks_mut(NODE_CHUNK)
                .zip(state.masses.par_chunks(NODE_CHUNK))
                .for_each(|(f, m)| {
                    for (fi, &mi) in f.iter_mut().zip(m) {
                        for k in 0..3 {
                            fi[k] += mi * g[k];
                        }
                    }
                });
        }
        self.last_powers = powers;
        Ok(())
    }

    /// Advances one step of velocity Verlet:
    /// `v(n+1/2) = v(n) + dt/2 a(n)`, `x(n+1) = x(n) + dt v(n+1/2)`,
    /// `a(n+1) = f(x(n+1), v(n+1/2)) / m`, `v(n+1) = v(n+1/2) + dt/2 a(n+1)`.
    pub fn advance(&mut self) -> Result<(), SolverError> {
        let dt = self.dt;
        let half = 0.5 * dt;
        {
            let s = &mut self.state;
            s.positions
                .par_chunks_mut(NODE_CHUNK)
                .zip(s.velocities.par_chunks_mut(NODE_CHUNK))
                .zip(s.forces.par_chunks(NODE_CHUNK))
                .zip(s.inverse_masses.par_chunks(NODE_CHUNK))
                .for_each(|(((x, v), f), im)| {
                    for i in 0..x.len() {
                        for k in 0..3 {
                            v[i][k] += half * f[i][k] * im[i];
                            x[i][k] += dt * v[i][k];
                        }
                    }
                });
        }
        let (step, time) = (self.step + 1, self.time + dt);
        self.time = time;
        if let Err(e) = self.compute_forces() {
            // An inverted element or a refused contact step during the time loop is a
            // step-size problem: report it with the step, time, dt and bound.
            return Err(match e {
                SolverError::Elastic { .. } | SolverError::Contact(_) => {
                    self.unstable(step, time, e.to_string())
                }
                other => other,
            });
        }
        // Work and dissipation over the step, from powers at the half-step velocities.
        self.contribution_work += dt * self.last_powers.external;
        self.damping_dissipated += dt * self.last_powers.damping;
        self.friction_dissipated += self.last_powers.friction_energy;
        let finite = {
            let s = &mut self.state;
            s.velocities
                .par_chunks_mut(NODE_CHUNK)
                .zip(s.forces.par_chunks(NODE_CHUNK))
                .zip(s.inverse_masses.par_chunks(NODE_CHUNK))
                .map(|((v, f), im)| {
                    let mut ok = true;
                    for i in 0..v.len() {
                        for k in 0..3 {
                            v[i][k] += half * f[i][k] * im[i];
                            ok &= v[i][k].is_finite();
                        }
                    }
                    ok
                })
                // `reduce` (not `all`) so that every chunk is updated; `&&` is
                // order-independent, so the result does not depend on scheduling.
                .reduce(|| true, |a, b| a && b)
        };
        self.step = step;
        self.time = time;
        if !finite {
            return Err(self.unstable(step, time, "a velocity became non-finite".into()));
        }
        if self.guard.check_interval > 0 && step % self.guard.check_interval == 0 {
            self.check_energy()?;
        }
        Ok(())
    }

    /// The energy scale the balance error is measured against: the largest of the initial
    /// energy, the external work, the dissipated energy and the guard's absolute floor.
    pub fn energy_scale(&self, e: &EnergyReport) -> f64 {
        self.initial_energy
            .abs()
            .max(e.external_work.abs())
            .max(e.dissipated.abs())
            .max(self.guard.energy_floor * self.wave_energy)
            .max(f64::MIN_POSITIVE)
    }

    /// `|balance error| / energy scale`.
    pub fn relative_balance_error(&self, e: &EnergyReport) -> f64 {
        e.balance_error.abs() / self.energy_scale(e)
    }

    /// The contact contribution, if the simulation has one.
    pub fn contact(&self) -> Option<&crate::ContactForces> {
        self.contributions.iter().find_map(|c| c.as_contact())
    }

    /// The contact contribution, mutable (e.g. to restore friction history from a file).
    pub fn contact_mut(&mut self) -> Option<&mut crate::ContactForces> {
        self.contributions
            .iter_mut()
            .find_map(|c| c.as_contact_mut())
    }

    /// Stops the run if the energy balance error has grown past the guard's tolerance.
    pub fn check_energy(&self) -> Result<EnergyReport, SolverError> {
        let e = self.energy();
        let scale = self.energy_scale(&e);
        let relative = self.relative_balance_error(&e);
        if !relative.is_finite() || relative > self.guard.energy_tolerance {
            return Err(self.unstable(
                self.step,
                self.time,
                format!(
                    "energy balance error {:.3e} J is {:.3e} of the energy scale {:.3e} J (tolerance {})",
                    e.balance_error, relative, scale, self.guard.energy_tolerance
                ),
            ));
        }
        Ok(e)
    }

    fn unstable(&self, step: u64, time: f64, reason: String) -> SolverError {
        SolverError::Unstable {
            step,
            time,
            dt: self.dt,
            bound: self.bound.dt,
            bound_source: self.bound.source.clone(),
            reason,
        }
    }

    fn view(&self) -> NodeView<'_> {
        NodeView {
            positions: &self.state.positions,
            velocities: &self.state.velocities,
            masses: &self.state.masses,
            time: self.time,
            dt: self.dt,
        }
    }

    /// The energies now.
    pub fn energy(&self) -> EnergyReport {
        let s = &self.state;
        let kinetic = s.kinetic_energy(0..s.len());
        let strain = self.elastic.potential_energy(self.view());
        let other_potential: f64 = self
            .contributions
            .iter()
            .map(|c| c.potential_energy(self.view()))
            .sum();
        // Gravity is uniform and constant: its work is exactly sum m g . (x - x0).
        let g = self.gravity;
        let gravity_work: f64 = if g == [0.0; 3] {
            0.0
        } else {
            s.positions
                .iter()
                .zip(&s.reference)
                .zip(&s.masses)
                .map(|((x, x0), &m)| {
                    m * (g[0] * (x[0] - x0[0]) + g[1] * (x[1] - x0[1]) + g[2] * (x[2] - x0[2]))
                })
                .sum()
        };
        let external_work = gravity_work + self.contribution_work;
        let dissipated = self.damping_dissipated + self.friction_dissipated;
        EnergyReport {
            time: self.time,
            kinetic,
            strain,
            other_potential,
            damping_dissipated: self.damping_dissipated,
            friction_dissipated: self.friction_dissipated,
            external_work,
            dissipated,
            balance_error: kinetic + strain + other_potential + dissipated
                - external_work
                - self.initial_energy,
        }
    }
}
