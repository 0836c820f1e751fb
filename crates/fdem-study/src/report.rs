//! The study's results from its finished runs: per-run rows, per-test means and spreads
//! over seeds, errors against each series' original, the paper's Table 5 beside ours,
//! and `runs.csv`.

use crate::metrics::{Errors, Measured, RunMetrics, errors, mean_and_spread, measure};
use crate::run::{RunRecord, finished_record, run_dir};
use crate::{RunDef, Series, StudyError, StudyOptions, expand};
use fdem_solver::ParticleModel;
use std::path::Path;

/// The paper's Table 5: mean normal contact force at the peak (N) per test. E1 is printed
/// as 80.30 in the paper; its other rows divide to 280.3 (docs/MODEL.md section 9).
pub const PAPER_MEAN_FORCE: &[(&str, f64)] = &[
    ("E1", 280.3),
    ("E2", 1172.19),
    ("E3", 2703.42),
    ("E4", 3831.52),
    ("E2s", 1046.27),
    ("E3s", 2070.92),
    ("E4s", 3109.17),
    ("B1", 306.42),
    ("B2", 788.65),
    ("B3", 1323.10),
    ("B2s", 658.55),
    ("B3s", 1122.34),
];

/// The header of `runs.csv`: the columns docs/STUDY.md defines, one row per run.
pub const RUNS_HEADER: &str = "test,h,exact_scaling,model,order,seed,particles,peak_eta,\
eps_a_peak,residual_eta,eps_v_final,mean_normal_force,strong_share,weak_share,wall_seconds,\
cpu_seconds,steps,series,model_used,initial_modulus,max_contraction,dilatancy_onset,\
coordination_number,element_steps,surface_node_steps,peak_memory_mb,preparation_wall_seconds,\
consolidation_wall_seconds,shear_wall_seconds,energy_balance_consolidation,energy_balance_shear";

/// One finished run with what it measured.
#[derive(Clone, Debug)]
pub struct Entry {
    /// Its definition.
    pub run: RunDef,
    /// Its record.
    pub record: RunRecord,
    /// Its curve and metrics.
    pub measured: Measured,
}

/// The runs of one test in one model and order, over seeds, with their errors against
/// the series' original in the same model and order.
#[derive(Clone, Debug)]
pub struct Group {
    /// Series.
    pub series: String,
    /// Test.
    pub test: String,
    /// Coarse-graining factor.
    pub h: f64,
    /// Exact scaling.
    pub exact_scaling: bool,
    /// Model asked for.
    pub model: String,
    /// Element order.
    pub order: String,
    /// Whether this is the series' original.
    pub reference: bool,
    /// Indices into the entries, by seed.
    pub entries: Vec<usize>,
    /// The errors of each seed against the reference (empty without a reference).
    pub errors: Vec<Errors>,
    /// Mean CPU seconds of its runs (preparation and test, all threads): the cost the
    /// study charts, since it is far less disturbed than wall time when other work shares
    /// the machine (docs/STUDY.md).
    pub cpu_seconds: f64,
    /// Spread of the CPU seconds.
    pub cpu_spread: f64,
    /// Speed-up of the whole run over the reference's (mean CPU seconds).
    pub speedup: f64,
}

/// Everything the results document and charts are made of.
#[derive(Clone, Debug)]
pub struct Results {
    /// The finished runs.
    pub entries: Vec<Entry>,
    /// Their groups, in series order.
    pub groups: Vec<Group>,
}

/// The other models whose finished runs the results include beside the asked one.
const MODELS: [ParticleModel; 3] = [
    ParticleModel::Deformable,
    ParticleModel::Rigid,
    ParticleModel::Auto,
];

/// Reads every finished run of `series` in `out`: the asked model's and, for the model
/// comparison, the other models' with the same order choice and seeds.
pub fn gather(
    series: &[Series],
    options: &StudyOptions,
    out: &Path,
) -> Result<Results, StudyError> {
    let mut entries = Vec::new();
    let models =
        std::iter::once(options.model).chain(MODELS.into_iter().filter(|m| *m != options.model));
    for model in models {
        let opts = StudyOptions {
            model,
            ..options.clone()
        };
        for run in expand(series, &opts, true)? {
            let Some(record) = finished_record(out, &run)? else {
                continue;
            };
            let Some(peak) = &record.peak else {
                continue;
            };
            let measured = measure(&run_dir(out, &run), peak)?;
            entries.push(Entry {
                run,
                record,
                measured,
            });
        }
    }
    let groups = group(&entries);
    Ok(Results { entries, groups })
}

fn group(entries: &[Entry]) -> Vec<Group> {
    let mut groups: Vec<Group> = Vec::new();
    for (i, e) in entries.iter().enumerate() {
        let r = &e.record;
        match groups.iter_mut().find(|g| {
            g.series == r.series && g.test == r.test && g.model == r.model && g.order == r.order
        }) {
            Some(g) => g.entries.push(i),
            None => groups.push(Group {
                series: r.series.clone(),
                test: r.test.clone(),
                h: r.h,
                exact_scaling: r.exact_scaling,
                model: r.model.clone(),
                order: r.order.clone(),
                reference: e.run.reference,
                entries: vec![i],
                errors: Vec::new(),
                cpu_seconds: f64::NAN,
                cpu_spread: f64::NAN,
                speedup: f64::NAN,
            }),
        }
    }
    for g in &mut groups {
        let (mean, spread) =
            mean_and_spread(g.entries.iter().map(|&i| entries[i].record.cpu_seconds()));
        g.cpu_seconds = mean;
        g.cpu_spread = spread;
    }
    let snapshot = groups.clone();
    for g in &mut groups {
        let Some(reference) = snapshot.iter().find(|r| {
            r.reference && r.series == g.series && r.model == g.model && r.order == g.order
        }) else {
            continue;
        };
        g.speedup = reference.cpu_seconds / g.cpu_seconds;
        g.errors = g
            .entries
            .iter()
            .map(|&i| {
                let seed = entries[i].run.seed;
                // The reference run of the same seed, else its first seed.
                let r = reference
                    .entries
                    .iter()
                    .copied()
                    .find(|&k| entries[k].run.seed == seed)
                    .unwrap_or(reference.entries[0]);
                errors(&entries[i].measured, &entries[r].measured)
            })
            .collect();
    }
    groups
}

impl Results {
    /// The metrics of a group's runs.
    pub fn metrics<'a>(&'a self, g: &'a Group) -> impl Iterator<Item = &'a RunMetrics> + 'a {
        g.entries.iter().map(|&i| &self.entries[i].measured.metrics)
    }

    /// Mean and spread of one metric over a group's seeds.
    pub fn metric(&self, g: &Group, f: fn(&RunMetrics) -> f64) -> (f64, f64) {
        mean_and_spread(self.metrics(g).map(f))
    }

    /// Mean and spread of one error over a group's seeds (NaN without a reference).
    pub fn error(g: &Group, f: fn(&Errors) -> f64) -> (f64, f64) {
        mean_and_spread(g.errors.iter().map(f))
    }

    /// The reference group of `g` (same series, model and order).
    pub fn reference_of(&self, g: &Group) -> Option<&Group> {
        self.groups.iter().find(|r| {
            r.reference && r.series == g.series && r.model == g.model && r.order == g.order
        })
    }

    /// Total wall and CPU seconds of every run.
    pub fn total_cost(&self) -> (f64, f64) {
        self.entries.iter().fold((0.0, 0.0), |(w, c), e| {
            (w + e.record.wall_seconds(), c + e.record.cpu_seconds())
        })
    }
}

fn csv_number(x: f64) -> String {
    if x.is_finite() {
        format!("{x}")
    } else {
        String::new()
    }
}

/// `runs.csv`: one row per finished run ([`RUNS_HEADER`]).
pub fn runs_csv(results: &Results) -> String {
    let mut text = String::from(RUNS_HEADER);
    text.push('\n');
    for e in &results.entries {
        let (r, m) = (&e.record, &e.measured.metrics);
        let row = [
            r.test.clone(),
            csv_number(r.h),
            r.exact_scaling.to_string(),
            r.model.clone(),
            r.order.clone(),
            r.seed.to_string(),
            r.particles.to_string(),
            csv_number(m.peak_eta),
            csv_number(m.eps_a_peak),
            csv_number(m.residual_eta),
            csv_number(m.eps_v_final),
            csv_number(m.mean_normal_force),
            csv_number(m.strong_share),
            csv_number(m.weak_share),
            csv_number(r.wall_seconds()),
            csv_number(r.cpu_seconds()),
            r.steps().to_string(),
            r.series.clone(),
            format!("\"{}\"", r.model_used),
            csv_number(m.initial_modulus),
            csv_number(m.max_contraction),
            csv_number(m.dilatancy_onset),
            csv_number(m.coordination_number),
            r.element_steps().to_string(),
            r.surface_node_steps().to_string(),
            r.peak_memory_bytes.map_or(String::new(), |b| {
                format!("{:.1}", b as f64 / (1u64 << 20) as f64)
            }),
            csv_number(r.preparation.wall_seconds),
            csv_number(r.consolidation.wall_seconds),
            csv_number(r.shear.wall_seconds),
            csv_number(e.measured.energy_balance[0]),
            csv_number(e.measured.energy_balance[1]),
        ];
        text.push_str(&row.join(","));
        text.push('\n');
    }
    text
}
