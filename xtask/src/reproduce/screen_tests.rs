#![allow(clippy::unwrap_used)]
//! The screen summary (issue 38 item 5): it fits 40 lines for both presets, equal reasons
//! are printed once, and every number of its table is the value certificate.json holds
//! (the file parsed back from disk, not the in-memory document). Reuses the two preset runs
//! of `tests::fixture`.

use serde_json::Value;

use super::tests::{fixture, read_json};
use super::*;

/// The table of a screen summary: header cells, then one row of cells per method (the
/// simulated column joined back into one cell).
fn table(screen: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let mut lines = screen.lines().skip_while(|l| !l.starts_with("  method"));
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split_whitespace()
        .map(str::to_string)
        .collect();
    let rows = lines
        .take_while(|l| !l.starts_with("  [") && !l.starts_with("verdict:"))
        .map(|l| {
            let cells: Vec<&str> = l.split_whitespace().collect();
            let mut row: Vec<String> = cells.iter().take(9).map(|c| (*c).to_string()).collect();
            row.push(cells.get(9..).map_or_else(String::new, |c| c.join(" ")));
            row
        })
        .collect();
    (header, rows)
}

/// A cell without its footnote mark (`void[1]` → `void`) and the mark's number.
fn strip(cell: &str) -> (&str, Option<usize>) {
    match cell.split_once('[') {
        Some((v, rest)) => (v, rest.trim_end_matches(']').parse().ok()),
        None => (cell, None),
    }
}

/// The footnote `[n]`'s text.
fn footnote(screen: &str, n: usize) -> String {
    let tag = format!("  [{n}] ");
    screen
        .lines()
        .find_map(|l| l.strip_prefix(&tag))
        .unwrap_or_else(|| panic!("no footnote [{n}] in\n{screen}"))
        .to_string()
}

/// An integer cell against a JSON integer or null (then the cell is a word with a reason).
fn check_k(what: &str, cell: &str, json: &Value, screen: &str) {
    let (v, mark) = strip(cell);
    match json.as_u64() {
        Some(k) => assert_eq!(v.parse::<u64>().ok(), Some(k), "{what}: {cell} vs {json}"),
        None => {
            assert!(json.is_null(), "{what}: {json}");
            assert!(
                ["void", "none", "n/c", "n/a", "-"].contains(&v),
                "{what}: {cell}"
            );
            if v != "-" {
                footnote(
                    screen,
                    mark.unwrap_or_else(|| panic!("{what}: {cell} has no reason")),
                );
            }
        }
    }
}

/// A 4-significant-digit cell against a JSON number or null (`-`).
fn check_num(what: &str, cell: &str, json: &Value) {
    match json.as_f64() {
        Some(x) => {
            let y: f64 = cell.parse().unwrap_or_else(|_| panic!("{what}: `{cell}`"));
            assert!(
                (y - x).abs() <= 5e-4 * x.abs(),
                "{what}: printed {y}, certificate.json {x}"
            );
        }
        None => assert_eq!(cell, "-", "{what}: {json}"),
    }
}

#[test]
fn the_default_output_of_both_presets_fits_40_lines() {
    let f = fixture();
    // stdout of each job, plus the one progress line per job on stderr.
    let text: String = [&f.paper, &f.certified]
        .iter()
        .map(|o| format!("[job] progress\n{}", printed(o, 1.0, false)))
        .collect();
    let n = text.lines().count();
    assert!(n <= 40, "{n} lines:\n{text}");
    // The long summary is not printed by default, and is with -v.
    assert!(!text.contains("Premises of Theorem 1"), "{text}");
    let verbose = printed(&f.paper, 1.0, true);
    for needle in [
        "Premises of Theorem 1",
        "paper (published)",
        "Trajectory check",
    ] {
        assert!(verbose.contains(needle), "{needle}");
    }
    assert!(verbose.ends_with(&format!("{} (1.0 s)\n", f.paper.screen)));
}

#[test]
fn equal_reasons_are_one_footnote() {
    let s = &fixture().paper.screen;
    assert!(
        s.lines().all(|l| l == l.trim_end()),
        "trailing blanks:\n{s}"
    );
    let (_, rows) = table(s);
    assert_eq!(rows.len(), 8, "{s}");
    // Every method of the paper preset is void for the same reason (ρ ≥ 1): one footnote.
    assert!(rows.iter().all(|r| r[1] == "void[1]"), "{s}");
    assert!(
        footnote(s, 1).starts_with("K_min void: rho < 1 fails"),
        "{s}"
    );
    let notes: Vec<&str> = s.lines().filter(|l| l.starts_with("  [")).collect();
    let mut texts: Vec<&str> = notes
        .iter()
        .map(|l| l.split_once("] ").unwrap().1)
        .collect();
    texts.sort_unstable();
    texts.dedup();
    assert_eq!(texts.len(), notes.len(), "a reason printed twice:\n{s}");
    // Every mark has its footnote.
    for r in &rows {
        for c in r {
            if let (_, Some(n)) = strip(c) {
                footnote(s, n);
            }
        }
    }
}

#[test]
fn the_screen_table_shows_what_certificate_json_holds() {
    let f = fixture();
    for (preset, o) in [(Preset::Paper, &f.paper), (Preset::Certified, &f.certified)] {
        let s = &o.screen;
        let doc = read_json(&f.out.join(preset.name()).join("certificate.json"));
        let (header, rows) = table(s);
        assert_eq!(header, screen::TABLE_HEADER, "{s}");
        let solvers = doc["solvers"].as_array().unwrap();
        assert_eq!(rows.len(), solvers.len(), "{s}");
        for (i, (row, sv)) in rows.iter().zip(solvers).enumerate() {
            let name = sv["solver"].as_str().unwrap();
            assert_eq!(row[0], name);
            check_k(&format!("{name} K_min"), &row[1], &sv["k_min"], s);
            check_k(&format!("{name} K_glob"), &row[2], &sv["k_glob"], s);
            check_k(&format!("{name} K_chain"), &row[3], &sv["k_chain"], s);
            check_k(&format!("{name} K_f32"), &row[4], &sv["k_f32"], s);
            assert_eq!(
                sv["k_f32"].is_null(),
                sv["f32_reason"].as_str().is_some_and(|r| !r.is_empty()),
                "{name}: k_f32 xor f32_reason"
            );
            assert_eq!(doc["linear"][i]["solver"], name);
            check_k(
                &format!("{name} K_lin"),
                &row[5],
                &doc["linear"][i]["report"]["k_lin"],
                s,
            );
            assert_eq!(doc["regional"][i]["solver"], name);
            check_k(
                &format!("{name} K_reg"),
                &row[6],
                &doc["regional"][i]["k_reg"],
                s,
            );
            let g = &doc["asymptotic_gains"]["methods"][i];
            assert_eq!(g["solver"], name);
            check_num(&format!("{name} g_e"), &row[7], &g["theorem1"]["gain_e"]);
            check_num(&format!("{name} g_x"), &row[8], &g["theorem1"]["gain_x"]);
            // Only the scenario's method was simulated: its runs, each with its outcome.
            if name == doc["solver"] {
                let runs = doc["runs"].as_array().unwrap();
                assert!(!runs.is_empty());
                for r in runs {
                    let word = if r["diverged"] == true {
                        "diverged"
                    } else if r["error"].is_null() {
                        "bounded"
                    } else {
                        "stopped"
                    };
                    let cell = format!("K={} {word}", r["k"]);
                    assert!(row[9].contains(&cell), "{cell} not in `{}`", row[9]);
                }
            } else {
                assert!(row[9].is_empty(), "{name}: `{}`", row[9]);
            }
        }
        // The certified preset: K_min of the simulated method is the checked K.
        if preset == Preset::Certified {
            let own = solvers
                .iter()
                .find(|v| v["solver"] == doc["solver"])
                .unwrap();
            let k = own["k_min"].as_u64().unwrap();
            assert_eq!(doc["trajectory_check"]["k"].as_u64(), Some(k));
            assert_eq!(doc["trajectory_check"]["passed"], true);
            let row = rows.iter().find(|r| r[0] == doc["solver"]).unwrap();
            assert!(
                row[9].contains(&format!("K={k} bounded, Props. 1, 3 hold")),
                "{s}"
            );
        }
        // The one verdict, and where the rest is.
        let verdict = s.lines().find(|l| l.starts_with("verdict: ")).unwrap();
        assert_eq!(
            verdict,
            format!("verdict: {}", summary::verdict(&o.document))
        );
        // Its smallest certified K is the one verdict's floor (`at_scenario.k_min`), not
        // Theorem 1's K_min where another certificate certifies less: on the certified
        // preset Theorem L3's K_glob is below K_min, and the line says so.
        let method = doc["solver"].as_str().unwrap();
        let own = solvers.iter().find(|v| v["solver"] == method).unwrap();
        let floor = doc["at_scenario"]["k_min"].as_u64();
        let theorem1 = own["k_min"].as_u64();
        if preset == Preset::Certified {
            assert!(floor < theorem1, "{floor:?} vs {theorem1:?}");
            assert_eq!(floor, own["k_glob"].as_u64());
        } else {
            assert!(floor < own["k_glob"].as_u64(), "{floor:?}");
            assert_eq!(floor, own["k_chain"].as_u64());
        }
        match (floor, theorem1) {
            (Some(f), Some(k)) if f < k => assert!(
                verdict.contains(&format!(
                    "The smallest certified K for {method} is {f}, below Theorem 1's K_min = {k}"
                )),
                "{verdict}"
            ),
            // Theorem L3 decides at the scenario's K (the paper preset: K_min void) and the
            // chain certifies a K below K_glob: the line names both.
            (Some(f), None)
                if doc["at_scenario"]["certificate"] == "global"
                    && own["k_glob"].as_u64().is_some_and(|g| f < g) =>
            {
                let g = own["k_glob"].as_u64().unwrap();
                assert!(
                    verdict.contains(&format!(
                        "The smallest certified K for {method} is {f}, below K_glob = {g}: the \
                         iteration chain"
                    )),
                    "{verdict}"
                );
            }
            (Some(_), None) => {}
            _ => assert!(!verdict.contains("The smallest certified K"), "{verdict}"),
        }
        assert!(s.contains(SUMMARY_FILE), "{s}");
    }
}

#[test]
fn summary_md_holds_the_long_summary_and_the_work_log() {
    let f = fixture();
    let text = std::fs::read_to_string(f.out.join("paper").join(SUMMARY_FILE)).unwrap();
    for needle in [
        f.paper.screen.as_str(),
        f.paper.summary.as_str(),
        "## Work log",
        "[paper] computing the certificates (Theorem 1, the global loop certificate, the iteration chain)",
    ] {
        assert!(text.contains(needle), "summary.md lacks `{needle}`");
    }
}

/// A footnote's first clause ends at the first ": " outside parentheses: a 10-state plant's
/// K_reg note printed "the search stopped … uncertainty (largest K evaluated" — cut inside
/// "(largest K evaluated: 32)".
#[test]
fn first_clause_keeps_a_parenthesis_whole() {
    use super::screen::first_clause;
    assert_eq!(
        first_clause(
            "the search stopped before a K whose region contains the scenario's uncertainty \
             (largest K evaluated: 32): not computed at K = 64: the lifted model"
        ),
        "the search stopped before a K whose region contains the scenario's uncertainty \
         (largest K evaluated: 32)"
    );
    assert_eq!(first_clause("void: ρ = 1.2"), "void");
    assert_eq!(first_clause("no colon here"), "no colon here");
    assert_eq!(first_clause("ratio 3:1 kept: then"), "ratio 3:1 kept");
    assert_eq!(first_clause(&"é".repeat(130)).chars().count(), 120);
}
