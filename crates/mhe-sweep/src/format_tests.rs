#![allow(clippy::unwrap_used)]
use super::*;

#[test]
fn point_file_round_trip_and_truncation() {
    let f = PointFile {
        fingerprint: "00ff".into(),
        run_rows: vec!["0,1,pg,1,0,5,40,1.5".into(), "0,1,pg,1,1,6,40,2".into()],
        point_row: "0,1,pg,1,2,1".into(),
        edited: false,
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

/// Issue 37 (the survey's last findings): an edit that every cell check passes — a run cell
/// changed by one ulp, an optional cell emptied — is refused by the checksum line; and a
/// file written before the checksum (v1) is refused by name.
#[test]
fn an_edit_below_the_printed_digits_is_refused_by_the_checksum() {
    let f = PointFile {
        fingerprint: "00ff".into(),
        run_rows: vec!["0,1,pg,1,0,5,40,1".into(), "0,1,pg,1,1,6,40,0".into()],
        point_row: "0,1,pg,1,2,1".into(),
        edited: false,
    };
    let text = f.render();
    let p = Path::new("p.csv");
    assert!(!PointFile::parse(&text, p).unwrap().edited);
    for edited_text in [
        text.replacen("40,1\n", "40,0.9999999999999999\n", 1),
        text.replacen("40,0\n", "40,\n", 1),
    ] {
        assert_ne!(edited_text, text);
        let back = PointFile::parse(&edited_text, p).unwrap();
        assert!(back.edited, "edit not seen:\n{edited_text}");
    }
    let v1 = text.replacen("sweep point v2", "sweep point v1", 1);
    let e = PointFile::parse(&v1, p).unwrap_err().to_string();
    assert!(e.contains("older version"), "{e}");
}
