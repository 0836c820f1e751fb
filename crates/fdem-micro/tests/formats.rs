//! The CSV readers never panic on malformed input: random edits of valid files are either
//! read or refused with an error that names the file, a line and a column.

use fdem_micro::{MicroError, parse_nodes, parse_pairs};
use proptest::prelude::*;

const NODES: &str =
    "time,node,body,other_body,other_wall,x,y,z,depth,fnx,fny,fnz,ftx,fty,ftz,sliding
1e-3,7,0,1,,1e-3,2e-3,3e-3,1e-6,-1.5,0,0,0,0.1,0,0
1e-3,8,1,0,,1.1e-3,2e-3,3e-3,1e-6,2.5,0,0,0,-0.1,0,1
1e-3,9,1,,3,1e-3,-2e-3,3e-3,1e-6,0,4,0,0,0,0.2,0
";

const PAIRS: &str = "time,body,other_body,other_wall,fnx,fny,fnz,ftx,fty,ftz,nodes
1e-3,0,1,,-4,0,0,0,0.2,0,2
1e-3,1,,3,0,4,0,0,0,0.2,1
";

fn mutate(text: &str, pos: usize, kind: u8, byte: u8) -> String {
    let mut bytes = text.as_bytes().to_vec();
    let pos = pos % (bytes.len() + 1);
    match kind % 4 {
        0 if pos < bytes.len() => {
            bytes.remove(pos);
        }
        1 => bytes.insert(pos, byte),
        2 if pos < bytes.len() => bytes[pos] = byte,
        _ => bytes.truncate(pos),
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

fn located(e: &MicroError) -> bool {
    match e {
        MicroError::Csv {
            file,
            line,
            column,
            message,
        } => file == "in.csv" && *line >= 1 && !column.is_empty() && !message.is_empty(),
        _ => false,
    }
}

#[test]
fn the_valid_files_are_read() {
    assert_eq!(
        parse_nodes(NODES.as_bytes(), "in.csv").unwrap().rows.len(),
        3
    );
    assert_eq!(parse_pairs(PAIRS.as_bytes(), "in.csv").unwrap().len(), 2);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn edited_files_never_panic(edits in proptest::collection::vec((any::<usize>(), any::<u8>(), 32u8..127), 1..4)) {
        let (mut nodes, mut pairs) = (NODES.to_string(), PAIRS.to_string());
        for &(pos, kind, byte) in &edits {
            nodes = mutate(&nodes, pos, kind, byte);
            pairs = mutate(&pairs, pos, kind, byte);
        }
        if let Err(e) = parse_nodes(nodes.as_bytes(), "in.csv") {
            prop_assert!(located(&e), "{}", e);
        }
        if let Err(e) = parse_pairs(pairs.as_bytes(), "in.csv") {
            prop_assert!(located(&e), "{}", e);
        }
    }

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,300}") {
        let _ = parse_nodes(text.as_bytes(), "in.csv");
        let _ = parse_pairs(text.as_bytes(), "in.csv");
    }
}
