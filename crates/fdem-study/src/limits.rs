//! The limits of the rigid model (docs/STABILITY.md): the quick test with rigid and with
//! deformable particles over the particles' Young's modulus, at the same penalty and
//! confining stress, over several seeds; the difference of the two models against the
//! seed-to-seed scatter, and where the `auto` criterion switches.

use crate::metrics::{mean_and_spread, measure};
use crate::run::{StudyObserver, finished_record, run_dir, run_study};
use crate::{RunDef, StudyError};
use fdem_core::fs::write_atomically;
use fdem_mesh::ElementOrder;
use fdem_solver::ParticleModel;
use fdem_triaxial::quick_spec;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// The particles' Young's moduli of the comparison (Pa): the paper's 40 GPa down to where
/// the quick specimen's particles deflect by tens of percent of their overlaps.
pub const MODULI: [f64; 4] = [40e9, 10e9, 2.5e9, 0.625e9];
/// Seeds per modulus and model.
pub const SEEDS: u64 = 3;
/// Settling time of the preparations, in the time the platens take to close by one
/// largest diameter (twice `fdem_triaxial::DEFAULT_SETTLE_DIAMETERS`).
const SETTLE_DIAMETERS: f64 = 8.0;

/// The quick test at modulus `e` in `model` with elements of `order`, seed `seed`.
fn limit_run(
    e: f64,
    model: ParticleModel,
    order: ElementOrder,
    seed: u64,
) -> Result<RunDef, StudyError> {
    let mut spec = quick_spec();
    spec.material.youngs_modulus = e;
    spec.model = model;
    spec.mesh.order = order;
    spec.seed = seed;
    // Twice the default settling time: the softest particles settle slowly, and the
    // criterion ends the settling as soon as it holds.
    let d_max = spec.largest_simulated_size();
    spec.preparation.settle_time = Some(SETTLE_DIAMETERS * d_max / spec.preparation.platen_speed);
    spec.name = format!("quick-E{}GPa", e / 1e9);
    spec.validate(&spec.name)?;
    Ok(RunDef {
        series: "limits".into(),
        test: spec.name.clone(),
        reference: false,
        seed,
        spec,
    })
}

/// The runs: the quick test at each modulus in both models (linear elements), and at the
/// quick specimen's own modulus with quadratic elements; seeds 1 to [`SEEDS`].
pub fn limit_runs() -> Result<Vec<RunDef>, StudyError> {
    let mut runs = Vec::new();
    for e in MODULI {
        for model in [ParticleModel::Rigid, ParticleModel::Deformable] {
            for seed in 1..=SEEDS {
                runs.push(limit_run(e, model, ElementOrder::Linear, seed)?);
            }
        }
    }
    for seed in 1..=SEEDS {
        runs.push(limit_run(
            quick_spec().material.youngs_modulus,
            ParticleModel::Deformable,
            ElementOrder::Quadratic,
            seed,
        )?);
    }
    Ok(runs)
}

/// Linear against quadratic elements on the quick test at its own modulus.
#[derive(Clone, Debug)]
pub struct ElementComparison {
    /// Peak eta (mean, spread), linear then quadratic.
    pub peak_eta: [(f64, f64); 2],
    /// Volumetric strain at the end (mean, spread), linear then quadratic.
    pub eps_v_final: [(f64, f64); 2],
    /// Mean CPU seconds of the whole run, linear then quadratic.
    pub cpu_seconds: [f64; 2],
    /// Seeds finished, linear then quadratic.
    pub seeds: [usize; 2],
}

/// The metrics and CPU seconds of the finished runs among `runs`.
fn finished_metrics(
    dir: &Path,
    runs: &[&RunDef],
) -> Result<Vec<(crate::metrics::RunMetrics, f64)>, StudyError> {
    let mut out = Vec::new();
    for run in runs {
        if let Some(record) = finished_record(dir, run)?
            && let Some(peak) = &record.peak
        {
            let m = measure(&run_dir(dir, run), peak)?;
            out.push((m.metrics, record.cpu_seconds()));
        }
    }
    Ok(out)
}

/// The element comparison from the finished runs in `dir`.
pub fn compare_elements(dir: &Path) -> Result<ElementComparison, StudyError> {
    let runs = limit_runs()?;
    let e = quick_spec().material.youngs_modulus;
    let pick = |order: ElementOrder| -> Vec<&RunDef> {
        runs.iter()
            .filter(|r| {
                r.spec.material.youngs_modulus == e
                    && r.model() == ParticleModel::Deformable
                    && r.spec.mesh.order == order
            })
            .collect()
    };
    let sets = [
        finished_metrics(dir, &pick(ElementOrder::Linear))?,
        finished_metrics(dir, &pick(ElementOrder::Quadratic))?,
    ];
    let stat = |k: usize, f: fn(&crate::metrics::RunMetrics) -> f64| {
        mean_and_spread(sets[k].iter().map(|(m, _)| f(m)))
    };
    Ok(ElementComparison {
        peak_eta: [stat(0, |m| m.peak_eta), stat(1, |m| m.peak_eta)],
        eps_v_final: [stat(0, |m| m.eps_v_final), stat(1, |m| m.eps_v_final)],
        cpu_seconds: [0, 1].map(|k| mean_and_spread(sets[k].iter().map(|(_, c)| *c)).0),
        seeds: [sets[0].len(), sets[1].len()],
    })
}

/// The section of STABILITY.md on linear against quadratic elements.
pub fn elements_markdown(c: &ElementComparison) -> String {
    let [(l, ls), (q, qs)] = c.peak_eta;
    let [(lv, lvs), (qv, qvs)] = c.eps_v_final;
    format!(
        "## Linear against quadratic elements\n\n\
         The quick test at its own modulus with deformable particles, {SEEDS} seeds each: \
         peak eta {l:.4} ± {ls:.4} (linear) against {q:.4} ± {qs:.4} (quadratic), a \
         difference of {:+.4} against a scatter of {:.4}; eps_v at the end {:.2} ± {:.2} % \
         against {:.2} ± {:.2} %; {:.0} against {:.0} CPU seconds per run ({:.1} times). \
         Concentric shells (docs/MESHES.md) are not yet a specimen option, so one shell \
         against several is measured on single particles only (docs/VERIFICATION.md). \
         Where exact scaling itself breaks (gravity left unscaled) is measured in \
         docs/SCALING.md, \"Where it fails\".\n\n",
        q - l,
        ls.max(qs),
        100.0 * lv,
        100.0 * lvs,
        100.0 * qv,
        100.0 * qvs,
        c.cpu_seconds[0],
        c.cpu_seconds[1],
        c.cpu_seconds[1] / c.cpu_seconds[0],
    )
}

/// The `auto` criterion's deflection ratio (particle deflection over contact overlap) of
/// the quick specimen at modulus `e`, and the model it chooses.
pub fn auto_choice(e: f64) -> Result<(f64, ParticleModel), StudyError> {
    let mut spec = quick_spec();
    spec.material.youngs_modulus = e;
    spec.model = ParticleModel::Auto;
    let counts = spec.counts()?;
    let estimate = counts.classes[0]
        .auto
        .ok_or_else(|| StudyError::Definition("the auto model gave no estimate".into()))?;
    Ok((estimate.ratio, estimate.model))
}

/// One modulus of the comparison.
#[derive(Clone, Debug)]
pub struct LimitPoint {
    /// Young's modulus (Pa).
    pub modulus: f64,
    /// `auto`'s deflection ratio and choice.
    pub ratio: f64,
    /// `rigid` or `deformable`.
    pub auto: ParticleModel,
    /// Peak eta over seeds (mean, spread), rigid then deformable.
    pub peak_eta: [(f64, f64); 2],
    /// Volumetric strain at the end over seeds (mean, spread), rigid then deformable.
    pub eps_v_final: [(f64, f64); 2],
    /// CPU seconds of the test (mean), rigid then deformable.
    pub cpu_seconds: [f64; 2],
    /// Seeds finished, rigid then deformable.
    pub seeds: [usize; 2],
}

/// Runs what is not finished of [`limit_runs`] in `dir` and collects the comparison.
pub fn run_limits(
    dir: &Path,
    observer: &mut dyn StudyObserver,
    interrupt: &AtomicBool,
) -> Result<Vec<LimitPoint>, StudyError> {
    let runs = limit_runs()?;
    run_study(&runs, dir, observer, interrupt, false)?;
    let mut points = Vec::new();
    for e in MODULI {
        let (ratio, auto) = auto_choice(e)?;
        let of = |model: ParticleModel| -> Vec<&RunDef> {
            runs.iter()
                .filter(|r| {
                    r.spec.material.youngs_modulus == e
                        && r.model() == model
                        && r.spec.mesh.order == ElementOrder::Linear
                })
                .collect()
        };
        let per_model = [
            finished_metrics(dir, &of(ParticleModel::Rigid))?,
            finished_metrics(dir, &of(ParticleModel::Deformable))?,
        ];
        let stat = |k: usize, f: fn(&crate::metrics::RunMetrics) -> f64| {
            mean_and_spread(per_model[k].iter().map(|(m, _)| f(m)))
        };
        points.push(LimitPoint {
            modulus: e,
            ratio,
            auto,
            peak_eta: [stat(0, |m| m.peak_eta), stat(1, |m| m.peak_eta)],
            eps_v_final: [stat(0, |m| m.eps_v_final), stat(1, |m| m.eps_v_final)],
            cpu_seconds: [0, 1].map(|k| mean_and_spread(per_model[k].iter().map(|(_, c)| *c)).0),
            seeds: [per_model[0].len(), per_model[1].len()],
        });
    }
    Ok(points)
}

/// `limits.csv`: one row per modulus.
pub fn limits_csv(points: &[LimitPoint]) -> String {
    let mut t = String::from(
        "youngs_modulus,auto_ratio,auto_model,peak_eta_rigid,peak_eta_rigid_sd,\
         peak_eta_deformable,peak_eta_deformable_sd,eps_v_final_rigid,eps_v_final_rigid_sd,\
         eps_v_final_deformable,eps_v_final_deformable_sd,cpu_seconds_rigid,\
         cpu_seconds_deformable,seeds_rigid,seeds_deformable\n",
    );
    for p in points {
        t.push_str(&format!(
            "{:e},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            p.modulus,
            p.ratio,
            p.auto.name(),
            p.peak_eta[0].0,
            p.peak_eta[0].1,
            p.peak_eta[1].0,
            p.peak_eta[1].1,
            p.eps_v_final[0].0,
            p.eps_v_final[0].1,
            p.eps_v_final[1].0,
            p.eps_v_final[1].1,
            p.cpu_seconds[0],
            p.cpu_seconds[1],
            p.seeds[0],
            p.seeds[1]
        ));
    }
    t
}

/// The chart: peak eta and final eps_v against the modulus for both models with their
/// seed spread, and a vertical line where `auto` switches from deformable to rigid.
pub fn limits_chart(points: &[LimitPoint], path: &Path) -> Result<(), StudyError> {
    use fdem_core::plot::{
        self as figure, Draw, IntoLogRange, Marker, SeriesLabelPosition, Style, colour,
    };
    const STYLE: Style = Style {
        caption_size: 18,
        margin: 15,
        x_label_area: 45,
        y_label_area: 65,
        light_lines: None,
        axis_desc_size: None,
        label_size: None,
        legend_size: Some(12),
    };
    let (e0, e1) = (MODULI[3] / 1.5, MODULI[0] * 1.5);
    let switch = switch_modulus(points);
    type Pick = fn(&LimitPoint) -> [(f64, f64); 2];
    let panels: [(&str, &str, Pick, f64); 2] = [
        (
            "Peak stress ratio against the particles' modulus",
            "peak eta",
            |p| p.peak_eta,
            1.0,
        ),
        (
            "Volumetric strain at the end against the modulus",
            "eps_v at the end (%)",
            |p| p.eps_v_final,
            100.0,
        ),
    ];
    let svg = figure::svg((1200, 520), |root| {
        let (left, right) = root.split_horizontally(600);
        for (area, (title, y_desc, pick, scale)) in [&left, &right].into_iter().zip(panels) {
            let values: Vec<f64> = points
                .iter()
                .flat_map(|p| pick(p).map(|(m, s)| [scale * (m - s), scale * (m + s)]))
                .flatten()
                .filter(|v| v.is_finite())
                .collect();
            let (lo, hi) = values
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(*v), b.max(*v))
                });
            let pad = 0.1 * (hi - lo).max(1e-3);
            let (lo, hi) = if lo.is_finite() {
                (lo - pad, hi + pad)
            } else {
                (0.0, 1.0)
            };
            let mut chart = STYLE.chart(area, title, (e0..e1).log_scale(), lo..hi)?;
            chart.draw_axes(&STYLE, "Young's modulus of the particles (Pa)", y_desc)?;
            for (k, (name, marker)) in [("rigid", Marker::Triangle), ("deformable", Marker::Circle)]
                .into_iter()
                .enumerate()
            {
                let pts: Vec<(f64, f64, f64)> = points
                    .iter()
                    .map(|p| {
                        let (m, s) = pick(p)[k];
                        (p.modulus, scale * m, scale * s)
                    })
                    .filter(|p| p.1.is_finite())
                    .collect();
                chart.draw_markers(&pts, colour(k), marker, Some(name))?;
            }
            if let Some(e) = switch {
                chart.draw_reference_line((e, lo), (e, hi), figure::RGBColor(170, 0, 0))?;
            }
            chart.draw_legend(&STYLE, SeriesLabelPosition::UpperRight)?;
        }
        Ok(())
    })
    .map_err(|m| StudyError::file(path, format!("cannot be drawn: {m}")))?;
    write_atomically(path, svg).map_err(|e| StudyError::io("writing", path, e))
}

/// The modulus at which `auto`'s deflection ratio equals its threshold (the ratio is
/// inversely proportional to the modulus; docs/MODEL.md section 12), from the first
/// point.
fn switch_modulus(points: &[LimitPoint]) -> Option<f64> {
    let p = points.first()?;
    Some(p.modulus * p.ratio / fdem_solver::DEFAULT_AUTO_THRESHOLD)
}

/// The section of STABILITY.md on the limits of the rigid model.
pub fn limits_markdown(points: &[LimitPoint]) -> String {
    use std::fmt::Write as _;
    let mut d = String::new();
    let _ = writeln!(d, "## The limits of the rigid model\n");
    let _ = writeln!(
        d,
        "The quick test (its specimen, penalty and confining stress) with rigid and with \
         deformable (linear) particles, over the particles' Young's modulus, {SEEDS} seeds \
         each (`results/limits.csv`, `results/limits.svg`; a seed whose preparation or test \
         failed is left out, and the last column says how many finished). \"Scatter\" is the larger of the \
         two models' seed-to-seed standard deviations; `auto` is the choice of the \
         deflection criterion (particle deflection over contact overlap against {}).\n",
        fdem_solver::DEFAULT_AUTO_THRESHOLD
    );
    let _ = writeln!(
        d,
        "| E (GPa) | deflection / overlap | auto | peak eta rigid | peak eta deformable | difference | scatter | eps_v end rigid (%) | eps_v end deformable (%) | CPU s rigid / deformable | seeds rigid / deformable |"
    );
    let _ = writeln!(d, "|---|---|---|---|---|---|---|---|---|---|---|");
    let mut verdicts = Vec::new();
    for p in points {
        let [(r, rs), (f, fs)] = p.peak_eta;
        let scatter = rs.max(fs);
        let diff = r - f;
        let within = diff.abs() <= scatter;
        if p.auto == ParticleModel::Rigid {
            verdicts.push((p.modulus, within));
        }
        let _ = writeln!(
            d,
            "| {} | {:.3} | {} | {r:.4} ± {rs:.4} | {f:.4} ± {fs:.4} | {diff:+.4} | {scatter:.4}{} | {:.2} ± {:.2} | {:.2} ± {:.2} | {:.0} / {:.0} | {} / {} |",
            p.modulus / 1e9,
            p.ratio,
            p.auto.name(),
            if within { " (within)" } else { "" },
            100.0 * p.eps_v_final[0].0,
            100.0 * p.eps_v_final[0].1,
            100.0 * p.eps_v_final[1].0,
            100.0 * p.eps_v_final[1].1,
            p.cpu_seconds[0],
            p.cpu_seconds[1],
            p.seeds[0],
            p.seeds[1],
        );
    }
    let _ = writeln!(d);
    if verdicts.is_empty() {
        let _ = writeln!(d, "`auto` picks rigid particles at none of these moduli.\n");
    } else {
        let _ = writeln!(
            d,
            "Where `auto` picks rigid particles (E = {} GPa), the rigid and deformable peak \
             stress ratios differ by no more than the seed-to-seed scatter: {}.\n",
            verdicts
                .iter()
                .map(|v| format!("{}", v.0 / 1e9))
                .collect::<Vec<_>>()
                .join(", "),
            if verdicts.iter().all(|v| v.1) {
                "holds at every such modulus"
            } else {
                "does NOT hold at every such modulus"
            }
        );
    }
    d
}

/// The files of the limits section, written into `data`.
pub fn write_limits(points: &[LimitPoint], data: &Path) -> Result<Vec<PathBuf>, StudyError> {
    let csv = data.join("limits.csv");
    write_atomically(&csv, limits_csv(points)).map_err(|e| StudyError::io("writing", &csv, e))?;
    let svg = data.join("limits.svg");
    limits_chart(points, &svg)?;
    Ok(vec![csv, svg])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_switches_within_the_moduli_and_its_ratio_goes_as_one_over_e() {
        let (stiff, soft) = (
            auto_choice(MODULI[0]).unwrap(),
            auto_choice(MODULI[3]).unwrap(),
        );
        assert_eq!(stiff.1, ParticleModel::Rigid, "ratio {}", stiff.0);
        assert_eq!(soft.1, ParticleModel::Deformable, "ratio {}", soft.0);
        // w / delta is proportional to 1 / E at fixed force and patch (docs/MODEL.md 12).
        let expected = stiff.0 * MODULI[0] / MODULI[3];
        assert!(
            (soft.0 / expected - 1.0).abs() < 1e-9,
            "{} vs {expected}",
            soft.0
        );
        assert_eq!(
            limit_runs().unwrap().len(),
            (MODULI.len() * 2 + 1) * SEEDS as usize
        );
    }
}
