//! The test's stored-energy jump log (`TestOptions::energy_jumps`): every contact whose
//! stored energy jumps by more than a threshold in one step, with its cause
//! (fdem_contact::events), written to `energy_jumps.csv` and summed per phase and cause
//! in `summary.json` (docs/TRIAXIAL.md, "Energy balance").

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use fdem_contact::Counterpart;
use fdem_contact::events::EnergyJump;
use serde::Serialize;

/// Header of `energy_jumps.csv`: one row per jump.
pub const JUMPS_HEADER: &str = "phase,time,node,body,counterpart,kind,energy_before,energy_after,\
     depth_before,depth_after,edge_before,edge_after";

/// The jumps of one cause in one phase, summed.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct JumpTotal {
    /// `consolidation` or `shear`.
    pub phase: String,
    /// The cause, e.g. `vanished:fold_discard` (fdem_contact::events::JumpKind::name).
    pub kind: String,
    /// Number of jumps.
    pub count: u64,
    /// Stored energy they added to the model (J; negative where energy was lost).
    pub energy_added: f64,
    /// Sum of their magnitudes (J).
    pub energy_magnitude: f64,
}

/// The log while the test runs: the CSV and the totals.
#[derive(Debug)]
pub(crate) struct JumpTally {
    file: BufWriter<File>,
    totals: BTreeMap<(&'static str, String), JumpTotal>,
}

fn counterpart_name(c: Counterpart) -> String {
    match c {
        Counterpart::Body(b) => format!("body {b}"),
        Counterpart::Wall(w) => format!("wall {w}"),
    }
}

impl JumpTally {
    /// Creates `path` with its header.
    pub(crate) fn create(path: &Path) -> io::Result<JumpTally> {
        let mut file = BufWriter::new(File::create(path)?);
        writeln!(file, "{JUMPS_HEADER}")?;
        Ok(JumpTally {
            file,
            totals: BTreeMap::new(),
        })
    }

    /// Adds the jumps of one step at `time` in `phase`.
    pub(crate) fn add(
        &mut self,
        phase: &'static str,
        time: f64,
        jumps: &[EnergyJump],
    ) -> io::Result<()> {
        for j in jumps {
            let kind = j.kind.name();
            writeln!(
                self.file,
                "{phase},{time:e},{},{},{},{kind},{:e},{:e},{:e},{:e},{},{}",
                j.node,
                j.body,
                counterpart_name(j.counterpart),
                j.energy_before,
                j.energy_after,
                j.depth_before,
                j.depth_after,
                j.edge_before,
                j.edge_after
            )?;
            let total = self
                .totals
                .entry((phase, kind.clone()))
                .or_insert_with(|| JumpTotal {
                    phase: phase.to_string(),
                    kind,
                    ..JumpTotal::default()
                });
            total.count += 1;
            total.energy_added += j.change();
            total.energy_magnitude += j.change().abs();
        }
        Ok(())
    }

    /// Flushes the file and returns the totals, by phase and cause.
    pub(crate) fn finish(&mut self) -> io::Result<Vec<JumpTotal>> {
        self.file.flush()?;
        Ok(self.totals.values().cloned().collect())
    }
}
