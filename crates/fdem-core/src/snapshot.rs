//! The contact snapshot format (docs/MICRO.md): node-level snapshots
//! (`contacts/nodes_NNNNNN.csv`) and per body-pair sums (`contacts/pairs_NNNNNN.csv`).
//!
//! The solver writes them, the micro-analysis reads them; both go through this module, so
//! the headers, the row layout and the number formatting exist once. Values are written
//! with Rust's shortest round-trip formatting in exponent form (`{:e}`), so a file read
//! back gives the same bits.
//!
//! The reader finds columns by their header name, so other codes can produce the files:
//! their order is free, extra columns are ignored and blank space around fields is
//! trimmed. Malformed input is refused with a [`CsvError`] naming file, line and column.

use serde::Serialize;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::Read;

/// Header of a node-level snapshot as `fdem run --contacts` writes it.
pub const NODES_HEADER: &str =
    "time,node,body,other_body,other_wall,x,y,z,depth,fnx,fny,fnz,ftx,fty,ftz,sliding";
/// Header of a per body-pair ground-truth file as `fdem run --contacts` writes it.
pub const PAIRS_HEADER: &str = "time,body,other_body,other_wall,fnx,fny,fnz,ftx,fty,ftz,nodes";

/// What a node (or a pair's body) touches: the `other_body` and `other_wall` columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Counterpart {
    /// A face (or the nodes) of this body.
    Body(u32),
    /// The rigid wall of this index.
    Wall(u32),
    /// Not recorded (both `other_body` and `other_wall` empty): the snapshot of a code
    /// that puts action and reaction on the nodes of both bodies; the micro-analysis pairs
    /// such nodes geometrically.
    Unknown,
}

impl Counterpart {
    /// Appends the two columns `other_body,other_wall`: the filled one and an empty one
    /// (both empty for [`Counterpart::Unknown`]).
    pub fn write_columns(self, out: &mut String) {
        let _ = match self {
            Counterpart::Body(b) => write!(out, "{b},"),
            Counterpart::Wall(w) => write!(out, ",{w}"),
            Counterpart::Unknown => out.write_char(','),
        };
    }
}

/// Appends the three columns of a vector (`x`, `y`, `z` or `fnx`, `fny`, `fnz`, ...), each
/// after a comma, in the format's number formatting.
pub fn write_vector_columns(out: &mut String, v: [f64; 3]) {
    let _ = write!(out, ",{:e},{:e},{:e}", v[0], v[1], v[2]);
}

/// One row of a node-level snapshot: a surface node in contact and the force on it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NodeRow {
    /// Node id (unique within the snapshot; the row index when the column is absent).
    pub node: u64,
    /// Body the node belongs to.
    pub body: u32,
    /// What the node touches.
    pub counterpart: Counterpart,
    /// Node position (m).
    pub position: [f64; 3],
    /// Penetration depth (m); 0 when the column is absent. Not used by the analysis.
    pub depth: f64,
    /// Normal contact force on the node (N).
    pub normal_force: [f64; 3],
    /// Tangential (friction) force on the node (N); 0 when the columns are absent.
    pub tangential_force: [f64; 3],
    /// Whether the contact slides; `false` when the column is absent.
    pub sliding: bool,
}

impl NodeRow {
    /// Appends the row, at snapshot time `time`, in the column order of [`NODES_HEADER`]
    /// with its newline.
    pub fn write_csv(&self, time: f64, out: &mut String) {
        let _ = write!(out, "{time:e},{},{},", self.node, self.body);
        self.counterpart.write_columns(out);
        write_vector_columns(out, self.position);
        let _ = write!(out, ",{:e}", self.depth);
        write_vector_columns(out, self.normal_force);
        write_vector_columns(out, self.tangential_force);
        let _ = writeln!(out, ",{}", u8::from(self.sliding));
    }
}

/// A node-level snapshot: every node contact at one instant.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Snapshot {
    /// Time of the snapshot (s): the `time` of the first row, 0 without rows or column.
    pub time: f64,
    /// The node contacts.
    pub rows: Vec<NodeRow>,
}

/// One row of a ground-truth file: the forces between a body and a counterpart, summed
/// over all node contacts between them.
///
/// fdem's convention (`fdem_contact::PairSum`): a body pair appears once, under its lower
/// body id, and the forces are those ON `body` (its nodes pressed into the other's faces,
/// plus the reactions of the other's nodes pressed into its faces). A wall pair holds the
/// force on the body.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PairRow {
    /// The body receiving the forces (the lower id of a body pair).
    pub body: u32,
    /// The other body (higher id) or a wall; never [`Counterpart::Unknown`] in a file
    /// the reader accepts.
    pub counterpart: Counterpart,
    /// Sum of the normal forces on `body` (N).
    pub normal_force: [f64; 3],
    /// Sum of the tangential forces on `body` (N).
    pub tangential_force: [f64; 3],
    /// Number of node contacts in the sum (0 when the column is absent).
    pub nodes: usize,
}

impl PairRow {
    /// Appends the row, at snapshot time `time`, in the column order of [`PAIRS_HEADER`]
    /// with its newline.
    pub fn write_csv(&self, time: f64, out: &mut String) {
        let _ = write!(out, "{time:e},{},", self.body);
        self.counterpart.write_columns(out);
        write_vector_columns(out, self.normal_force);
        write_vector_columns(out, self.tangential_force);
        let _ = writeln!(out, ",{}", self.nodes);
    }
}

/// A whole node-level snapshot file: [`NODES_HEADER`], then one line per row.
pub fn nodes_text(time: f64, rows: impl IntoIterator<Item = NodeRow>) -> String {
    let rows = rows.into_iter();
    let mut text = String::with_capacity(160 * (rows.size_hint().0 + 1));
    text.push_str(NODES_HEADER);
    text.push('\n');
    for r in rows {
        r.write_csv(time, &mut text);
    }
    text
}

/// A whole ground-truth file: [`PAIRS_HEADER`], then one line per row.
pub fn pairs_text(time: f64, rows: impl IntoIterator<Item = PairRow>) -> String {
    let rows = rows.into_iter();
    let mut text = String::with_capacity(100 * (rows.size_hint().0 + 1));
    text.push_str(PAIRS_HEADER);
    text.push('\n');
    for r in rows {
        r.write_csv(time, &mut text);
    }
    text
}

/// A malformed snapshot file: a missing or repeated column, an unparsable or out-of-range
/// value, a row with the wrong number of fields.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}:{column}: {message}")]
pub struct CsvError {
    /// The file (or `"<input>"` for text given in memory).
    pub file: String,
    /// 1-based line number (1 is the header).
    pub line: u64,
    /// The column: its header name, or its 1-based position when there is no name.
    pub column: String,
    /// What was wrong and how to fix it.
    pub message: String,
}

/// Column lookup and typed field parsing with file/line/column errors.
struct Table<'a> {
    file: &'a str,
    columns: HashMap<String, usize>,
    headers: Vec<String>,
}

impl<'a> Table<'a> {
    fn new(file: &'a str, headers: &csv::StringRecord) -> Result<Self, CsvError> {
        let headers: Vec<String> = headers.iter().map(|h| h.trim().to_string()).collect();
        let mut columns = HashMap::new();
        for (i, h) in headers.iter().enumerate() {
            if let Some(first) = columns.insert(h.clone(), i) {
                // An empty name is located by its position.
                let column = if h.is_empty() {
                    format!("#{}", i + 1)
                } else {
                    h.clone()
                };
                return Err(CsvError {
                    file: file.to_string(),
                    line: 1,
                    column,
                    message: format!(
                        "column `{h}` appears twice in the header (fields {} and {}); give \
                         every column its own name",
                        first + 1,
                        i + 1
                    ),
                });
            }
        }
        Ok(Table {
            file,
            columns,
            headers,
        })
    }

    fn error(&self, line: u64, column: &str, message: String) -> CsvError {
        CsvError {
            file: self.file.to_string(),
            line,
            column: column.to_string(),
            message,
        }
    }

    fn require(&self, name: &str, expected: &str) -> Result<usize, CsvError> {
        self.columns.get(name).copied().ok_or_else(|| {
            self.error(
                1,
                name,
                format!(
                    "the header has no column `{name}`; expected a header like `{expected}` \
                     (see docs/MICRO.md)"
                ),
            )
        })
    }

    fn optional(&self, name: &str) -> Option<usize> {
        self.columns.get(name).copied()
    }

    fn text<'r>(&self, record: &'r csv::StringRecord, column: usize) -> &'r str {
        record.get(column).map_or("", str::trim)
    }

    fn number(
        &self,
        record: &csv::StringRecord,
        line: u64,
        column: usize,
    ) -> Result<f64, CsvError> {
        let text = self.text(record, column);
        let name = &self.headers[column];
        let value: f64 = text.parse().map_err(|_| {
            self.error(
                line,
                name,
                format!("`{text}` is not a number (SI units expected)"),
            )
        })?;
        if !value.is_finite() {
            return Err(self.error(line, name, format!("`{text}` is not a finite number")));
        }
        Ok(value)
    }

    fn optional_number(
        &self,
        record: &csv::StringRecord,
        line: u64,
        column: Option<usize>,
    ) -> Result<f64, CsvError> {
        match column {
            Some(c) if !self.text(record, c).is_empty() => self.number(record, line, c),
            _ => Ok(0.0),
        }
    }

    fn id(&self, record: &csv::StringRecord, line: u64, column: usize) -> Result<u64, CsvError> {
        let text = self.text(record, column);
        let name = &self.headers[column];
        text.parse().map_err(|_| {
            self.error(
                line,
                name,
                format!("`{text}` is not an id (a non-negative integer)"),
            )
        })
    }

    fn id32(&self, record: &csv::StringRecord, line: u64, column: usize) -> Result<u32, CsvError> {
        let value = self.id(record, line, column)?;
        u32::try_from(value).map_err(|_| {
            self.error(
                line,
                &self.headers[column],
                format!("id {value} is too large (at most {})", u32::MAX),
            )
        })
    }

    fn vector(
        &self,
        record: &csv::StringRecord,
        line: u64,
        columns: [usize; 3],
    ) -> Result<[f64; 3], CsvError> {
        Ok([
            self.number(record, line, columns[0])?,
            self.number(record, line, columns[1])?,
            self.number(record, line, columns[2])?,
        ])
    }

    fn optional_vector(
        &self,
        record: &csv::StringRecord,
        line: u64,
        columns: [Option<usize>; 3],
    ) -> Result<[f64; 3], CsvError> {
        Ok([
            self.optional_number(record, line, columns[0])?,
            self.optional_number(record, line, columns[1])?,
            self.optional_number(record, line, columns[2])?,
        ])
    }

    /// `other_body` / `other_wall` of a row; both empty is `Unknown`.
    fn counterpart(
        &self,
        record: &csv::StringRecord,
        line: u64,
        body: u32,
        other_body: Option<usize>,
        other_wall: Option<usize>,
    ) -> Result<Counterpart, CsvError> {
        let filled = |c: Option<usize>| c.filter(|&c| !self.text(record, c).is_empty());
        match (filled(other_body), filled(other_wall)) {
            (Some(b), None) => {
                let other = self.id32(record, line, b)?;
                if other == body {
                    return Err(self.error(
                        line,
                        "other_body",
                        format!(
                            "body {body} cannot touch itself: other_body must differ from body"
                        ),
                    ));
                }
                Ok(Counterpart::Body(other))
            }
            (None, Some(w)) => Ok(Counterpart::Wall(self.id32(record, line, w)?)),
            (None, None) => Ok(Counterpart::Unknown),
            (Some(_), Some(_)) => Err(self.error(
                line,
                "other_wall",
                "both other_body and other_wall are filled: a row touches one body or one wall, \
                 leave the other column empty"
                    .to_string(),
            )),
        }
    }
}

fn csv_reader<R: Read>(input: R) -> csv::Reader<R> {
    csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(input)
}

fn csv_error(file: &str, e: &csv::Error) -> CsvError {
    let line = e.position().map_or(0, csv::Position::line);
    let (column, message) = match e.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => (
            format!("{}", len + 1),
            format!("the row has {len} fields but the header has {expected_len}"),
        ),
        csv::ErrorKind::Utf8 { err, .. } => (
            format!("{}", err.field() + 1),
            "the field is not valid UTF-8".to_string(),
        ),
        _ => ("1".to_string(), e.to_string()),
    };
    CsvError {
        file: file.to_string(),
        line,
        column,
        message,
    }
}

/// Parses a node-level snapshot from any reader; `file` names it in error messages.
///
/// Required columns: `body,x,y,z,fnx,fny,fnz`; optional: `time,node,other_body,other_wall,
/// depth,ftx,fty,ftz,sliding` (absent or empty optional values are 0, `false` or, for the
/// counterpart, [`Counterpart::Unknown`]).
///
/// # Errors
/// A [`CsvError`] for the first malformed header or field.
pub fn parse_nodes<R: Read>(input: R, file: &str) -> Result<Snapshot, CsvError> {
    let mut reader = csv_reader(input);
    let headers = reader.headers().map_err(|e| csv_error(file, &e))?.clone();
    let t = Table::new(file, &headers)?;
    let body = t.require("body", NODES_HEADER)?;
    let position = [
        t.require("x", NODES_HEADER)?,
        t.require("y", NODES_HEADER)?,
        t.require("z", NODES_HEADER)?,
    ];
    let normal = [
        t.require("fnx", NODES_HEADER)?,
        t.require("fny", NODES_HEADER)?,
        t.require("fnz", NODES_HEADER)?,
    ];
    let tangential = [t.optional("ftx"), t.optional("fty"), t.optional("ftz")];
    let (time, node, depth, sliding) = (
        t.optional("time"),
        t.optional("node"),
        t.optional("depth"),
        t.optional("sliding"),
    );
    let (other_body, other_wall) = (t.optional("other_body"), t.optional("other_wall"));
    let mut snapshot = Snapshot::default();
    let mut record = csv::StringRecord::new();
    let mut index = 0u64;
    while reader
        .read_record(&mut record)
        .map_err(|e| csv_error(file, &e))?
    {
        let line = record.position().map_or(0, csv::Position::line);
        if index == 0 {
            snapshot.time = t.optional_number(&record, line, time)?;
        }
        let b = t.id32(&record, line, body)?;
        let node_id = match node {
            Some(c) => t.id(&record, line, c)?,
            None => index,
        };
        let sliding = match sliding.map(|c| t.text(&record, c)) {
            None | Some("" | "0" | "false") => false,
            Some("1" | "true") => true,
            Some(other) => {
                return Err(t.error(
                    line,
                    "sliding",
                    format!("`{other}` is not a flag: use 0 or 1"),
                ));
            }
        };
        snapshot.rows.push(NodeRow {
            node: node_id,
            body: b,
            counterpart: t.counterpart(&record, line, b, other_body, other_wall)?,
            position: t.vector(&record, line, position)?,
            depth: t.optional_number(&record, line, depth)?,
            normal_force: t.vector(&record, line, normal)?,
            tangential_force: t.optional_vector(&record, line, tangential)?,
            sliding,
        });
        index += 1;
    }
    Ok(snapshot)
}

/// Parses a ground-truth file from any reader; `file` names it in error messages.
///
/// Required columns: `body,other_body,other_wall,fnx,fny,fnz` (one of the two counterpart
/// columns filled on every row); optional: `time,ftx,fty,ftz,nodes`. A body pair must be
/// listed under its lower id.
///
/// # Errors
/// A [`CsvError`] for the first malformed header, field or row.
pub fn parse_pairs<R: Read>(input: R, file: &str) -> Result<Vec<PairRow>, CsvError> {
    let mut reader = csv_reader(input);
    let headers = reader.headers().map_err(|e| csv_error(file, &e))?.clone();
    let t = Table::new(file, &headers)?;
    let body = t.require("body", PAIRS_HEADER)?;
    let other_body = t.require("other_body", PAIRS_HEADER)?;
    let other_wall = t.require("other_wall", PAIRS_HEADER)?;
    let normal = [
        t.require("fnx", PAIRS_HEADER)?,
        t.require("fny", PAIRS_HEADER)?,
        t.require("fnz", PAIRS_HEADER)?,
    ];
    let tangential = [t.optional("ftx"), t.optional("fty"), t.optional("ftz")];
    let nodes = t.optional("nodes");
    let mut out = Vec::new();
    let mut record = csv::StringRecord::new();
    while reader
        .read_record(&mut record)
        .map_err(|e| csv_error(file, &e))?
    {
        let line = record.position().map_or(0, csv::Position::line);
        let b = t.id32(&record, line, body)?;
        let counterpart = t.counterpart(&record, line, b, Some(other_body), Some(other_wall))?;
        match counterpart {
            Counterpart::Unknown => {
                return Err(t.error(
                    line,
                    "other_body",
                    "a ground-truth row must name its counterpart: fill other_body or other_wall"
                        .to_string(),
                ));
            }
            Counterpart::Body(o) if o < b => {
                return Err(t.error(
                    line,
                    "other_body",
                    format!(
                        "body pairs are listed under the lower id: write body {o}, other_body {b} \
                         and the force on body {o}"
                    ),
                ));
            }
            _ => {}
        }
        let n = match nodes {
            Some(c) if !t.text(&record, c).is_empty() => {
                usize::try_from(t.id(&record, line, c)?).unwrap_or(usize::MAX)
            }
            _ => 0,
        };
        out.push(PairRow {
            body: b,
            counterpart,
            normal_force: t.vector(&record, line, normal)?,
            tangential_force: t.optional_vector(&record, line, tangential)?,
            nodes: n,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    impl NodeRow {
        fn at(node: u64, body: u32, counterpart: Counterpart) -> Self {
            NodeRow {
                node,
                body,
                counterpart,
                position: [0.0; 3],
                depth: 0.0,
                normal_force: [0.0; 3],
                tangential_force: [0.0; 3],
                sliding: false,
            }
        }
    }

    fn error_of(text: &str) -> String {
        match parse_nodes(text.as_bytes(), "n.csv") {
            Ok(s) => panic!("accepted: {s:?}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn reads_the_fdem_format() {
        let text = format!(
            "{NODES_HEADER}\n\
             1e-3,7,0,1,,0.1,0.2,0.3,1e-6,1,2,3,0.1,0.2,0.3,0\n\
             1e-3,8,0,,2,0.1,0.2,0.3,1e-6,1,2,3,0,0,0,1\n"
        );
        let s = parse_nodes(text.as_bytes(), "n.csv").unwrap();
        assert_eq!(s.time, 1e-3);
        assert_eq!(s.rows.len(), 2);
        assert_eq!(s.rows[0].counterpart, Counterpart::Body(1));
        assert_eq!(s.rows[1].counterpart, Counterpart::Wall(2));
        assert_eq!(s.rows[0].normal_force, [1.0, 2.0, 3.0]);
        assert!(s.rows[1].sliding);
    }

    #[test]
    fn minimal_columns_in_any_order() {
        let text = "fnz,fny,fnx,z,y,x,body\n3,2,1,0.3,0.2,0.1,4\n";
        let s = parse_nodes(text.as_bytes(), "n.csv").unwrap();
        assert_eq!(s.rows[0].body, 4);
        assert_eq!(s.rows[0].position, [0.1, 0.2, 0.3]);
        assert_eq!(s.rows[0].normal_force, [1.0, 2.0, 3.0]);
        assert_eq!(s.rows[0].counterpart, Counterpart::Unknown);
        assert_eq!(s.rows[0].tangential_force, [0.0; 3]);
    }

    #[test]
    fn malformed_files_name_file_line_and_column() {
        let head = "body,x,y,z,fnx,fny,fnz,other_body,other_wall";
        let e = error_of(&format!("{head}\n0,0,0,0,1,1,1,,\n0,0,abc,0,1,1,1,,\n"));
        assert!(e.starts_with("n.csv:3:y: `abc` is not a number"), "{e}");
        let e = error_of(&format!("{head}\n0,0,0,0,1,NaN,1,,\n"));
        assert!(e.starts_with("n.csv:2:fny:"), "{e}");
        let e = error_of(&format!("{head}\n-1,0,0,0,1,1,1,,\n"));
        assert!(e.starts_with("n.csv:2:body:"), "{e}");
        let e = error_of(&format!("{head}\n0,0,0,0,1,1,1,1,2\n"));
        assert!(e.contains("both other_body and other_wall"), "{e}");
        let e = error_of(&format!("{head}\n3,0,0,0,1,1,1,3,\n"));
        assert!(e.contains("cannot touch itself"), "{e}");
        let e = error_of(&format!("{head}\n0,0,0,0,1,1\n"));
        assert!(e.starts_with("n.csv:2:"), "{e}");
        assert!(e.contains("fields"), "{e}");
        let e = error_of("body,x,y,fnx,fny,fnz\n");
        assert!(
            e.starts_with("n.csv:1:z: the header has no column `z`"),
            "{e}"
        );
        let e = error_of("body,x,y,z,z,fnx,fny,fnz\n");
        assert!(e.contains("appears twice"), "{e}");
        // Found by the formats property test: two empty names are located by position.
        let e = error_of("body,x,y,z,fnx,fny,fnz,,\n");
        assert!(
            e.starts_with("n.csv:1:#9:") && e.contains("fields 8 and 9"),
            "{e}"
        );
        let e = error_of("body,x,y,z,fnx,fny,fnz,sliding\n0,0,0,0,1,1,1,maybe\n");
        assert!(e.starts_with("n.csv:2:sliding:"), "{e}");
    }

    #[test]
    fn ground_truth_rows_are_checked() {
        let ok = format!("{PAIRS_HEADER}\n0,1,2,,1,2,3,0,0,0,4\n0,1,,0,1,2,3,0,0,0,2\n");
        let p = parse_pairs(ok.as_bytes(), "p.csv").unwrap();
        assert_eq!(p[0].counterpart, Counterpart::Body(2));
        assert_eq!(p[1].counterpart, Counterpart::Wall(0));
        assert_eq!(p[0].nodes, 4);
        let bad = format!("{PAIRS_HEADER}\n0,2,1,,1,2,3,0,0,0,4\n");
        let e = parse_pairs(bad.as_bytes(), "p.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.csv:2:other_body: body pairs are listed under the lower id"),
            "{e}"
        );
        let bad = format!("{PAIRS_HEADER}\n0,2,,,1,2,3,0,0,0,4\n");
        let e = parse_pairs(bad.as_bytes(), "p.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("must name its counterpart"), "{e}");
    }

    #[test]
    fn rows_are_written_in_header_order() {
        let row = NodeRow {
            position: [0.1, -0.2, 1.0 / 3.0],
            normal_force: [1.5, 0.0, -2.0],
            tangential_force: [0.0, 0.1, 0.0],
            depth: 1e-7,
            sliding: true,
            ..NodeRow::at(3, 1, Counterpart::Body(0))
        };
        let wall = NodeRow {
            counterpart: Counterpart::Wall(2),
            sliding: false,
            ..row
        };
        let unknown = NodeRow {
            counterpart: Counterpart::Unknown,
            ..wall
        };
        let text = nodes_text(0.25, [row, wall, unknown]);
        let expected = format!(
            "{NODES_HEADER}\n\
             2.5e-1,3,1,0,,1e-1,-2e-1,3.333333333333333e-1,1e-7,1.5e0,0e0,-2e0,0e0,1e-1,0e0,1\n\
             2.5e-1,3,1,,2,1e-1,-2e-1,3.333333333333333e-1,1e-7,1.5e0,0e0,-2e0,0e0,1e-1,0e0,0\n\
             2.5e-1,3,1,,,1e-1,-2e-1,3.333333333333333e-1,1e-7,1.5e0,0e0,-2e0,0e0,1e-1,0e0,0\n"
        );
        assert_eq!(text, expected);
        let back = parse_nodes(text.as_bytes(), "n.csv").unwrap();
        assert_eq!(back.time, 0.25);
        assert_eq!(back.rows, [row, wall, unknown]);

        let pair = PairRow {
            nodes: 4,
            normal_force: [-1.5, 0.0, 2.0],
            tangential_force: [0.0, -0.1, 0.0],
            counterpart: Counterpart::Body(1),
            body: 0,
        };
        let text = pairs_text(0.25, [pair]);
        assert_eq!(
            text,
            format!("{PAIRS_HEADER}\n2.5e-1,0,1,,-1.5e0,0e0,2e0,0e0,-1e-1,0e0,4\n")
        );
        assert_eq!(parse_pairs(text.as_bytes(), "p.csv").unwrap(), [pair]);
    }
}
