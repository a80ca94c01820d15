//! Point files: one cell of a finished point file set to another value is refused when a
//! resume or a merge reads it back (naming the file). A point file is reused instead of
//! recomputed, so a cell that is read back unchecked puts a number (or a verdict) into
//! points.csv that nothing computed.

use std::path::Path;
use std::time::Instant;

use xtask::sweep_engine::{NoProgress, RunOptions, Sweep, SweepConfig, SweepError};

use crate::{Tally, draw, runner, scratch};

/// Values written into a cell (besides a changed digit and a doubled number).
const VALUES: [&str; 22] = [
    "NaN",
    "-1",
    "inf",
    "-inf",
    "2",
    "0.5",
    "1e308",
    "",
    "x",
    "0",
    "1",
    "-0",
    "1e-320",
    "yes",
    "no",
    "void",
    "0.9999999999999999",
    "3",
    "-5",
    "1000000",
    "7.25",
    "\"a,b\"",
];

/// A tiny finished sweep with its theory columns (the double integrator, PG at K = 3 and
/// K_min-scale K, 2 seeds, T = 5): the sweep and the path and text of each point file.
pub fn finished(dir: &Path) -> (Sweep, Vec<(std::path::PathBuf, String)>) {
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/double-integrator.toml"
    );
    let text = format!(
        "scenario = \"{scenario}\"\nname = \"survey\"\nk = [3, 400]\nsolvers = [\"pg\"]\n\
         seeds = 2\nsteps = 5\nbase_seed = 11\ncertificate = true\n"
    );
    let sweep = Sweep::new(SweepConfig::from_toml_str(&text, dir).unwrap()).unwrap();
    let opts = RunOptions {
        out_dir: dir.to_path_buf(),
        threads: 1,
        shard: None,
    };
    sweep.run(&opts, &NoProgress).unwrap();
    let files = sweep
        .points()
        .iter()
        .map(|p| {
            let f = dir
                .join("points")
                .join(xtask::sweep_engine::point_file_name(p.index));
            let t = std::fs::read_to_string(&f).unwrap();
            (f, t)
        })
        .collect();
    (sweep, files)
}

/// Whether two cells say the same (equal text, or equal numbers).
fn same(a: &str, b: &str) -> bool {
    a == b
        || matches!((a.parse::<f64>(), b.parse::<f64>()),
            (Ok(x), Ok(y)) if x == y || (x.is_nan() && y.is_nan()))
}

pub fn survey(seed: u64, n: usize) -> Tally {
    let mut tally = Tally::default();
    let dir = scratch("points");
    let (sweep, files) = finished(&dir);
    assert_eq!(sweep.finished_points(&dir).unwrap().len(), files.len());
    let header_run = std::fs::read_to_string(dir.join("runs.csv")).unwrap();
    let header_point = std::fs::read_to_string(dir.join("points.csv")).unwrap();
    let run_cols: Vec<String> = header_run
        .lines()
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let point_cols: Vec<String> = header_point
        .lines()
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let mut rn = runner(seed, 4);
    let strategy = (
        0usize..64,
        1usize..64,
        0usize..256,
        0usize..VALUES.len() + 2,
        0usize..20,
    );
    for _ in 0..n {
        let (fi, line, col, value, digit) = draw(&mut rn, &strategy);
        let (file, original) = &files[fi % files.len()];
        let mut lines: Vec<String> = original.lines().map(str::to_string).collect();
        // Lines 1 ..= len − 2: the run rows, `=`, the summary row (the checksum line last).
        let line = 1 + line % (lines.len() - 2);
        if lines[line] == "=" {
            continue;
        }
        let summary = line == lines.len() - 2;
        let mut cells: Vec<String> = lines[line].split(',').map(str::to_string).collect();
        let c = col % cells.len();
        let old = cells[c].clone();
        let new = match value.checked_sub(2) {
            Some(v) => VALUES[v].to_string(),
            None if value == 0 => {
                let mut t: Vec<char> = old.chars().collect();
                let digits: Vec<usize> = (0..t.len()).filter(|&i| t[i].is_ascii_digit()).collect();
                if digits.is_empty() {
                    "9".into()
                } else {
                    let p = digits[digit % digits.len()];
                    t[p] = if t[p] == '9' {
                        '1'
                    } else {
                        char::from(t[p] as u8 + 1)
                    };
                    t.into_iter().collect()
                }
            }
            None => old
                .parse::<f64>()
                .map_or_else(|_| "7".into(), |v| format!("{}", 2.0 * v + 1.0)),
        };
        if same(&old, &new) {
            continue;
        }
        cells[c] = new.clone();
        lines[line] = cells.join(",");
        std::fs::write(file, lines.join("\n") + "\n").unwrap();
        let t0 = Instant::now();
        let read = sweep.finished_points(&dir);
        let took = t0.elapsed().as_secs_f64();
        tally.cases += 1;
        let column = if summary { &point_cols } else { &run_cols }
            .get(c)
            .cloned()
            .unwrap_or_else(|| format!("#{c}"));
        let row = if summary {
            "summary row".to_string()
        } else {
            format!("line {}", line + 1)
        };
        match read {
            Err(SweepError::PointFile { path, problem })
                if &path == file && !problem.is_empty() =>
            {
                tally.refused += 1;
            }
            Err(other) => tally.finding(format!(
                "edited point file: refused, but not as a point-file error naming it: {other}"
            )),
            Ok(_) => {
                tally.accepted += 1;
                tally.finding(format!(
                    "accepted-bad: {} {row}, column `{column}`: `{old}` → `{new}` read back \
                     as a finished point",
                    file.file_name().unwrap().to_string_lossy()
                ));
            }
        }
        if took > 1.0 {
            tally.finding(format!("reading the point files took {took:.2} s"));
        }
        std::fs::write(file, original).unwrap();
    }
    assert_eq!(sweep.finished_points(&dir).unwrap().len(), files.len());
    let _ = std::fs::remove_dir_all(&dir);
    tally
}

/// `file` with the cell of `column` in the summary row (or in the first run row) set to
/// `value`; the header is `points.csv`'s (or `runs.csv`'s) in `dir`.
fn edit_cell(dir: &Path, file: &str, summary: bool, column: &str, value: &str) -> String {
    let header =
        std::fs::read_to_string(dir.join(if summary { "points.csv" } else { "runs.csv" })).unwrap();
    let c = header
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|n| n == column)
        .unwrap();
    let text = std::fs::read_to_string(dir.join("points").join(file)).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    // The summary row is the last but one line (the checksum line follows it).
    let row = if summary { lines.len() - 2 } else { 1 };
    let mut cells: Vec<String> = lines[row].split(',').map(str::to_string).collect();
    cells[c] = value.to_string();
    lines[row] = cells.join(",");
    std::fs::write(dir.join("points").join(file), lines.join("\n") + "\n").unwrap();
    text
}

/// Found by the survey: a point file whose `certified` (or `k_min_cert`, `rho_lin`, …) was
/// edited was reused by a resume or a merge, so points.csv stated a verdict nothing
/// computed; and an emptied `sup_e` of a run went unnoticed (the quantiles of the others
/// did not change). Both are refused now, naming the file and the column.
#[test]
fn an_edited_verdict_or_an_emptied_metric_in_a_point_file_is_refused() {
    let dir = scratch("points-verdict");
    let (sweep, files) = finished(&dir);
    assert_eq!(sweep.finished_points(&dir).unwrap().len(), files.len());
    let cases = [
        (true, "certified", "yes", "certified"),
        (true, "k_min_cert", "1", "k_min_cert"),
        (true, "rho_lin", "0.5", "rho_lin"),
        (true, "void_reason", "edited", "void_reason"),
        (false, "sup_e", "", "sup_e"),
    ];
    for (summary, column, value, named) in cases {
        // Point 0 is K = 3, below K_min: "no".
        let original = edit_cell(&dir, "p00000.csv", summary, column, value);
        match sweep.finished_points(&dir) {
            Err(SweepError::PointFile { path, problem }) => {
                assert!(path.ends_with("p00000.csv"), "{}", path.display());
                assert!(
                    problem.contains(&format!("`{named}`")),
                    "{column}: {problem}"
                );
            }
            other => panic!("{column} = `{value}` accepted: {other:?}"),
        }
        std::fs::write(dir.join("points/p00000.csv"), original).unwrap();
    }
    assert_eq!(sweep.finished_points(&dir).unwrap().len(), files.len());
    let _ = std::fs::remove_dir_all(&dir);
}
