#![allow(clippy::unwrap_used)]
use super::*;

#[test]
fn point_file_round_trip_and_truncation() {
    let f = PointFile {
        fingerprint: "00ff".into(),
        run_rows: vec!["0,1,pg,1,0,5,40,1.5".into(), "0,1,pg,1,1,6,40,2".into()],
        point_row: "0,1,pg,1,2,1".into(),
    };
    let text = f.render();
    let p = Path::new("p.csv");
    assert_eq!(PointFile::parse(&text, p).unwrap(), f);
    // Any strict prefix of a point file is rejected (a torn write is never taken as a
    // finished point).
    for cut in 0..text.len() {
        assert!(
            PointFile::parse(&text[..cut], p).is_err(),
            "prefix {cut} accepted"
        );
    }
}

#[test]
fn settings_diff_names_what_differs() {
    let old = settings_text("aa", "k=[1, 2];seeds=3;k_c=[1, 5]");
    assert_eq!(
        settings_diff(&old, "bb", "k=[1, 2];seeds=4;k_c=[1, 2]"),
        "; settings that differ: seeds = 3 there, 4 here, k_c = [1, 5] there, [1, 2] here"
    );
    assert_eq!(
        settings_diff(&old, "bb", "k=[1, 2];seeds=3"),
        "; settings that differ: k_c = [1, 5] there, (none) here"
    );
    assert_eq!(
        settings_diff(&old, "bb", "k=[1, 2];seeds=3;k_c=[1, 5]"),
        "; the settings agree, so the scenario file differs"
    );
    // Nothing known: no record, a garbled one, or the same fingerprint.
    assert_eq!(settings_diff("", "bb", "k=[1]"), "");
    assert_eq!(settings_diff(&old, "aa", "k=[1]"), "");
}

#[test]
fn table_drops_timing_columns() {
    let t = Table::parse("a,wall_ms,b\n1,2.5,3\n4,9,6\n").unwrap();
    assert_eq!(t.without_timing(), "a,b\n1,3\n4,6");
    assert_eq!(t.number(1, "b"), Some(6.0));
    assert!(Table::parse("a,b\n1\n").is_err());
}
