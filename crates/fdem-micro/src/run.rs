//! Finding the snapshot of a run directory and analysing it in one call.

use crate::MicroError;
use crate::cluster::{ClusterParams, Clustering, cluster};
use crate::snapshot::{read_nodes, read_pairs};
use crate::stats::{Statistics, statistics};
use crate::validate::{DEFAULT_SIGNIFICANCE, Validation, validate};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Names of the peak snapshot that the triaxial test writes (node-level, then truth).
pub const PEAK_NAMES: [(&str, &str); 2] = [
    ("contacts_peak.csv", "pairs_peak.csv"),
    ("nodes_peak.csv", "pairs_peak.csv"),
];

/// Which snapshot of a run directory to analyse.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SnapshotChoice {
    /// The peak snapshot if the run has one, else the last numbered one.
    #[default]
    Auto,
    /// The last numbered snapshot `nodes_NNNNNN.csv`.
    Last,
    /// The peak snapshot `contacts_peak.csv` (or `nodes_peak.csv`).
    Peak,
    /// The numbered snapshot `nodes_NNNNNN.csv` with this number.
    Index(usize),
}

impl std::str::FromStr for SnapshotChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "auto" => Ok(SnapshotChoice::Auto),
            "last" => Ok(SnapshotChoice::Last),
            "peak" => Ok(SnapshotChoice::Peak),
            n => n.parse().map(SnapshotChoice::Index).map_err(|_| {
                format!("`{s}` is not a snapshot: use auto, last, peak or a number N (nodes_N.csv)")
            }),
        }
    }
}

/// The files of one snapshot.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SnapshotFiles {
    /// The node-level snapshot.
    pub nodes: PathBuf,
    /// Its ground truth, when present.
    pub pairs: Option<PathBuf>,
}

/// The ground-truth file that belongs to a node-level snapshot, by name:
/// `nodes_X.csv` -> `pairs_X.csv`, `contacts_peak.csv` -> `pairs_peak.csv`; `None` when
/// no such file exists.
pub fn truth_for(nodes: &Path) -> Option<PathBuf> {
    let name = nodes.file_name()?.to_str()?;
    let truth = if let Some(rest) = name.strip_prefix("nodes_") {
        format!("pairs_{rest}")
    } else if let Some(rest) = name.strip_prefix("contacts_") {
        format!("pairs_{rest}")
    } else {
        return None;
    };
    let path = nodes.with_file_name(truth);
    path.is_file().then_some(path)
}

fn numbered(folder: &Path) -> Vec<(usize, PathBuf)> {
    let Ok(read) = std::fs::read_dir(folder) else {
        return Vec::new();
    };
    let mut out: Vec<(usize, PathBuf)> = read
        .filter_map(Result::ok)
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            let digits = name.strip_prefix("nodes_")?.strip_suffix(".csv")?;
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                return None;
            }
            Some((digits.parse().ok()?, e.path()))
        })
        .collect();
    out.sort();
    out
}

/// Finds the snapshot to analyse. `path` is a run directory (snapshots in `contacts/` or
/// in the directory itself) or a node-level snapshot file; the ground truth is the
/// matching `pairs_*.csv` next to it.
pub fn locate_snapshot(path: &Path, choice: SnapshotChoice) -> Result<SnapshotFiles, MicroError> {
    let files = |nodes: PathBuf| SnapshotFiles {
        pairs: truth_for(&nodes),
        nodes,
    };
    if path.is_file() {
        return Ok(files(path.to_path_buf()));
    }
    if !path.is_dir() {
        return Err(MicroError::NoSnapshot {
            path: path.to_path_buf(),
            detail: "no such file or directory".to_string(),
        });
    }
    let folders = [path.join("contacts"), path.to_path_buf()];
    let peak = || {
        folders.iter().find_map(|f| {
            PEAK_NAMES
                .iter()
                .map(|(nodes, _)| f.join(nodes))
                .find(|p| p.is_file())
        })
    };
    let last = || {
        folders
            .iter()
            .find_map(|f| numbered(f).pop().map(|(_, p)| p))
    };
    let found = match choice {
        SnapshotChoice::Auto => peak().or_else(last),
        SnapshotChoice::Last => last(),
        SnapshotChoice::Peak => peak(),
        SnapshotChoice::Index(n) => folders
            .iter()
            .map(|f| f.join(format!("nodes_{n:06}.csv")))
            .find(|p| p.is_file()),
    };
    found.map(files).ok_or_else(|| MicroError::NoSnapshot {
        path: path.to_path_buf(),
        detail: match choice {
            SnapshotChoice::Peak => {
                "no contacts_peak.csv (or nodes_peak.csv) here or in contacts/; \
                 the triaxial test writes it at the peak"
                    .to_string()
            }
            SnapshotChoice::Index(n) => format!(
                "no nodes_{n:06}.csv here or in contacts/ (the snapshots present are numbered \
                 from 0 to the last output)"
            ),
            _ => "no contacts/nodes_NNNNNN.csv or contacts_peak.csv; run the scene with \
                  `fdem run SCENE --out DIR --contacts`"
                .to_string(),
        },
    })
}

/// Every snapshot of a run directory (numbered ones in order, then the peak one), or the
/// file itself when `path` is a snapshot file.
pub fn all_snapshots(path: &Path) -> Result<Vec<SnapshotFiles>, MicroError> {
    if path.is_file() {
        return locate_snapshot(path, SnapshotChoice::Auto).map(|f| vec![f]);
    }
    let folders = [path.join("contacts"), path.to_path_buf()];
    let mut out: Vec<SnapshotFiles> = folders
        .iter()
        .map(|f| numbered(f))
        .find(|n| !n.is_empty())
        .unwrap_or_default()
        .into_iter()
        .map(|(_, nodes)| SnapshotFiles {
            pairs: truth_for(&nodes),
            nodes,
        })
        .collect();
    if let Ok(peak) = locate_snapshot(path, SnapshotChoice::Peak) {
        out.push(peak);
    }
    if out.is_empty() {
        // The same message as for a single snapshot.
        locate_snapshot(path, SnapshotChoice::Auto)?;
    }
    Ok(out)
}

/// The number of bodies of a run from its `summary.json` (`None` when absent or without
/// a `bodies` field).
pub fn summary_bodies(run: &Path) -> Option<usize> {
    let text = std::fs::read_to_string(run.join("summary.json")).ok()?;
    let json: serde_json::Value = serde_json::from_str(&text).ok()?;
    json.get("bodies")?
        .as_u64()
        .and_then(|b| usize::try_from(b).ok())
}

/// Options of [`analyse`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AnalysisOptions {
    /// Clustering and pairing parameters.
    pub params: ClusterParams,
    /// Particle count for the coordination number (`None`: particles seen).
    pub particles: Option<usize>,
    /// Significance threshold of the validation (fraction of the mean normal force).
    pub significance: f64,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        AnalysisOptions {
            params: ClusterParams::default(),
            particles: None,
            significance: DEFAULT_SIGNIFICANCE,
        }
    }
}

/// Everything known about one snapshot.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Analysis {
    /// The files read.
    pub files: SnapshotFiles,
    /// The contacts.
    pub clustering: Clustering,
    /// Their statistics.
    pub statistics: Statistics,
    /// The comparison with the ground truth, when there is one.
    pub validation: Option<Validation>,
}

/// Reads, clusters, computes the statistics and validates one snapshot.
pub fn analyse(files: &SnapshotFiles, options: &AnalysisOptions) -> Result<Analysis, MicroError> {
    let s = options.significance;
    if !(s.is_finite() && s >= 0.0) {
        return Err(MicroError::InvalidParameter {
            name: "significance",
            value: s,
            requirement: "a finite fraction >= 0",
        });
    }
    let snapshot = read_nodes(&files.nodes)?;
    let clustering = cluster(&snapshot, &options.params)?;
    let statistics = statistics(&clustering, options.particles);
    let validation = match &files.pairs {
        Some(p) => Some(validate(&clustering, &read_pairs(p)?, s)),
        None => None,
    };
    Ok(Analysis {
        files: files.clone(),
        clustering,
        statistics,
        validation,
    })
}
