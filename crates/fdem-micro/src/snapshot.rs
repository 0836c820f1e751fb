//! Node-level contact snapshots and per body-pair sums: the input format (CSV), its
//! reader and writer.
//!
//! The format is the one `fdem run --contacts` writes (docs/MICRO.md describes it for
//! other codes), defined once in `fdem_core::snapshot` and re-exported here. Columns are
//! found by their header name, so their order is free and extra columns are ignored;
//! blank space around fields is trimmed.

use crate::MicroError;
use fdem_core::snapshot::{CsvError, nodes_text, pairs_text};
use std::io::Read;
use std::path::Path;

pub use fdem_core::snapshot::{
    Counterpart, NODES_HEADER, NodeRow, PAIRS_HEADER, PairRow, Snapshot,
};

impl From<CsvError> for MicroError {
    fn from(e: CsvError) -> Self {
        MicroError::Csv {
            file: e.file,
            line: e.line,
            column: e.column,
            message: e.message,
        }
    }
}

fn open(path: &Path) -> Result<std::io::BufReader<std::fs::File>, MicroError> {
    let file = std::fs::File::open(path).map_err(|e| MicroError::io("reading", path, e))?;
    Ok(std::io::BufReader::with_capacity(1 << 16, file))
}

/// Reads a node-level snapshot (`contacts/nodes_NNNNNN.csv` or any file of that format).
pub fn read_nodes(path: &Path) -> Result<Snapshot, MicroError> {
    parse_nodes(open(path)?, &path.display().to_string())
}

/// Parses a node-level snapshot from any reader; `file` names it in error messages.
///
/// Required columns: `body,x,y,z,fnx,fny,fnz`; optional: `time,node,other_body,other_wall,
/// depth,ftx,fty,ftz,sliding` (absent or empty optional values are 0, `false` or, for the
/// counterpart, [`Counterpart::Unknown`]).
pub fn parse_nodes<R: Read>(input: R, file: &str) -> Result<Snapshot, MicroError> {
    Ok(fdem_core::snapshot::parse_nodes(input, file)?)
}

/// Reads a ground-truth file (`contacts/pairs_NNNNNN.csv` or any file of that format).
pub fn read_pairs(path: &Path) -> Result<Vec<PairRow>, MicroError> {
    parse_pairs(open(path)?, &path.display().to_string())
}

/// Parses a ground-truth file from any reader; `file` names it in error messages.
///
/// Required columns: `body,other_body,other_wall,fnx,fny,fnz` (one of the two counterpart
/// columns filled on every row); optional: `time,ftx,fty,ftz,nodes`. A body pair must be
/// listed under its lower id.
pub fn parse_pairs<R: Read>(input: R, file: &str) -> Result<Vec<PairRow>, MicroError> {
    Ok(fdem_core::snapshot::parse_pairs(input, file)?)
}

/// Writes `text` to `path` through a temporary file and a rename.
pub(crate) fn write_atomically(path: &Path, text: &[u8]) -> Result<(), MicroError> {
    fdem_core::fs::write_atomically(path, text).map_err(|e| MicroError::io("writing", path, e))
}

/// Writes a node-level snapshot in the format of [`NODES_HEADER`] (atomically).
pub fn write_nodes(path: &Path, snapshot: &Snapshot) -> Result<(), MicroError> {
    let text = nodes_text(snapshot.time, snapshot.rows.iter().copied());
    write_atomically(path, text.as_bytes())
}

/// Writes a ground-truth file in the format of [`PAIRS_HEADER`] (atomically).
pub fn write_pairs(path: &Path, time: f64, pairs: &[PairRow]) -> Result<(), MicroError> {
    write_atomically(path, pairs_text(time, pairs.iter().copied()).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn format_errors_keep_file_line_and_column() {
        let e = parse_nodes(
            "body,x,y,z,fnx,fny,fnz\n0,0,abc,0,1,1,1\n".as_bytes(),
            "n.csv",
        )
        .unwrap_err();
        assert!(matches!(&e, MicroError::Csv { line: 2, column, .. } if column == "y"));
        assert!(
            e.to_string()
                .starts_with("n.csv:2:y: `abc` is not a number"),
            "{e}"
        );
        let e = parse_pairs("body,fnx\n".as_bytes(), "p.csv").unwrap_err();
        assert!(e.to_string().starts_with("p.csv:1:other_body:"), "{e}");
    }

    #[test]
    fn write_then_read_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let s = Snapshot {
            time: 0.25,
            rows: vec![NodeRow {
                node: 3,
                body: 1,
                counterpart: Counterpart::Body(0),
                position: [0.1, -0.2, 1.0 / 3.0],
                depth: 1e-7,
                normal_force: [1.5, 0.0, -2.0],
                tangential_force: [0.0, 0.1, 0.0],
                sliding: true,
            }],
        };
        let path = dir.path().join("nodes.csv");
        write_nodes(&path, &s).unwrap();
        assert_eq!(read_nodes(&path).unwrap(), s);
        let pairs = vec![PairRow {
            body: 0,
            counterpart: Counterpart::Body(1),
            normal_force: [-1.5, 0.0, 2.0],
            tangential_force: [0.0, -0.1, 0.0],
            nodes: 1,
        }];
        let path = dir.path().join("pairs.csv");
        write_pairs(&path, 0.25, &pairs).unwrap();
        assert_eq!(read_pairs(&path).unwrap(), pairs);
    }
}
