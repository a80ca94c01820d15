//! Unit tests of the figures' choices that need no simulation: names, notes, panel counts.

use super::*;

/// A stable plant with `n` states, one input and one output (no input or output bounds).
fn plant(n: usize) -> Scenario {
    // Row i of a matrix with n columns: `v` in column i, 0 elsewhere.
    let row = |i: usize, v: &'static str| {
        let mut r = vec!["0.0"; n];
        r[i] = v;
        format!("[{}]", r.join(", "))
    };
    let a: Vec<String> = (0..n).map(|i| row(i, "0.5")).collect();
    let b: Vec<String> = (0..n)
        .map(|i| if i == 0 { "[1.0]" } else { "[0.0]" }.to_string())
        .collect();
    let (lower, upper) = (
        vec!["-0.01"; n + 1].join(", "),
        vec!["0.01"; n + 1].join(", "),
    );
    let text = format!(
        "name = \"chain\"\n\
         plant = {{ a = [{}], b = [{}], c = [{}] }}\n\
         sets = {{ disturbance = {{ lower = [{lower}], upper = [{upper}] }} }}\n\
         simulation = {{ x0 = [{}], steps = 10 }}\n\
         mhe = {{ horizon = 3, eta = 0.8, iterations = 5 }}\n\
         mpc = {{ horizon = 3 }}\n",
        a.join(", "),
        b.join(", "),
        row(0, "1.0"),
        vec!["0.0"; n].join(", "),
    );
    Scenario::from_toml_str(&text).expect("a valid scenario")
}

#[test]
fn subscripts_are_unicode_digits() {
    assert_eq!(subscript(1), "₁");
    assert_eq!(subscript(12), "₁₂");
}

#[test]
fn without_runs_fig2c_is_a_note_and_a_wide_state_grid_says_what_it_leaves_out() {
    let f = figures(&plant(MAX_PANELS + 1), &[], 6);
    let names: Vec<&str> = f.files.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "fig2a_x1.svg",
            "fig2b_epsilon.svg",
            "norms.svg",
            "states.svg",
            "inputs.svg",
            "outputs.svg"
        ]
    );
    assert_eq!(
        f.notes,
        [
            "fig2c_w2_t6.svg not written: no run recorded the MHE window at t = 6".to_string(),
            "states.svg: 16 of 17 states drawn (x₁…x₁₆); every state is in trace.csv and trace.json"
                .to_string(),
        ]
    );
    let Figure::Grid(states) = &f.files[3].1 else {
        panic!("states.svg is a grid");
    };
    assert_eq!(states.panels.len(), MAX_PANELS);
    let Figure::Grid(inputs) = &f.files[4].1 else {
        panic!("inputs.svg is a grid");
    };
    assert_eq!(inputs.title, "Inputs u_t = π(x̂_t) (𝒰 has no bounds)");
    // Nothing to draw without runs: every figure is a note, none an error.
    let drawn = render(&plant(2), &[], 6);
    assert!(drawn.files.is_empty());
    assert_eq!(drawn.notes.len(), 1 + 6, "{:#?}", drawn.notes);
}
