//! Writes the case-study MHE QPs ([`benches::case_study`]) as JSON for the peer solvers
//! of `benches/peers/` (DAQP, OSQP, ProxQP): one file per preset of
//! [`MHE_PRESETS`] (paper M = 5, certified M = 9, m50 M = 50, cart-pendulum M = 9),
//! `<out>/<preset>.json`, holding
//!
//! - `H` (n × n, row-major nested arrays), `lower`, `upper` (`null` = unbounded),
//! - per instance t = M … T: `t`, `q`, the MHE warm start `z0`, and `z_star` (polished
//!   Clarabel reference, the accuracy yardstick),
//! - `fingerprint` (sum of all q entries: `cargo bench --bench mhe` accepts peer results
//!   only for the same instances), `horizon`, `n`, the scenario file and `eps`,
//! - `sparse`: the same QP uncondensed ([`benches::uncondensed`]): states as variables,
//!   dynamics as equality constraints — `n`, `P` (upper triangle, triplets `i`, `j`, `v`),
//!   `A_eq` (triplets, `m` rows), `lower`, `upper`, `z_index` (where z sits in v), and per
//!   instance `q`, `b` (right-hand side), `v0` (z⁰ lifted) and `v_star` (z* lifted).
//!
//! The QP is min ½zᵀHz + qᵀz s.t. lower ≤ z ≤ upper; uncondensed
//! min ½vᵀPv + qᵀv s.t. A_eq v = b, lower ≤ v ≤ upper.
//!
//! Run: `cargo run --release -p benches --bin export_qps -- [OUT_DIR]`
//! (default `target/peers`).

use std::path::PathBuf;
use std::process::ExitCode;

use benches::case_study::{CaseStudyQps, EPS, MHE_PRESETS};
use benches::uncondensed::{Triplets, Uncondensed};
use serde_json::{Value, json};

fn bound(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

fn triplets(t: &Triplets) -> Value {
    json!({ "i": t.rows, "j": t.cols, "v": t.vals })
}

/// The uncondensed form of the preset's QP and its instances.
fn sparse(qps: &CaseStudyQps) -> Value {
    let u = Uncondensed::new(qps);
    json!({
        "problem": "min 0.5 v'Pv + q'v  s.t.  A_eq v = b, lower <= v <= upper; v = (x0, w0, x1, w1, ...)",
        "n": u.n,
        "P": triplets(&u.p_upper),
        "A_eq": { "m": u.m_eq, "i": u.a_eq.rows, "j": u.a_eq.cols, "v": u.a_eq.vals },
        "lower": u.lower.iter().map(|&v| bound(v)).collect::<Vec<_>>(),
        "upper": u.upper.iter().map(|&v| bound(v)).collect::<Vec<_>>(),
        "z_index": u.z_index,
        "instances": qps.instances.iter().map(|i| json!({
            "q": u.linear_term(&i.theta),
            "b": u.rhs(&i.theta),
            "v0": u.lift(&i.z0, &i.theta),
            "v_star": u.lift(&i.z_star, &i.theta),
        })).collect::<Vec<_>>(),
    })
}

fn main() -> ExitCode {
    let out = std::env::args().nth(1).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/peers"),
        PathBuf::from,
    );
    if let Err(e) = std::fs::create_dir_all(&out) {
        eprintln!("cannot create `{}`: {e}", out.display());
        return ExitCode::FAILURE;
    }
    for preset in MHE_PRESETS {
        let qps = match CaseStudyQps::load(preset) {
            Ok(q) => q,
            Err(e) => {
                eprintln!("{}: {e}", preset.name);
                return ExitCode::FAILURE;
            }
        };
        let qp = &qps.qp;
        let n = qp.n();
        let h = qp.h_row_major();
        let doc = json!({
            "preset": preset.name,
            "scenario": preset.file,
            "horizon": qps.horizon(),
            "n": n,
            "eps": EPS,
            "problem": "min 0.5 z'Hz + q'z  s.t.  lower <= z <= upper (null = unbounded)",
            "H": (0..n).map(|i| h[i * n..(i + 1) * n].to_vec()).collect::<Vec<_>>(),
            "lower": qp.zset().lower().iter().map(|&v| bound(v)).collect::<Vec<_>>(),
            "upper": qp.zset().upper().iter().map(|&v| bound(v)).collect::<Vec<_>>(),
            "fingerprint": qps.instances.iter().flat_map(|i| &i.q).sum::<f64>(),
            "instances": qps.instances.iter().map(|i| json!({
                "t": i.t, "q": i.q, "z0": i.z0, "z_star": i.z_star,
            })).collect::<Vec<_>>(),
            "sparse": sparse(&qps),
        });
        let path = out.join(format!("{}.json", preset.name));
        let text = match serde_json::to_string(&doc) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("{}: {e}", preset.name);
                return ExitCode::FAILURE;
            }
        };
        if let Err(e) = std::fs::write(&path, text) {
            eprintln!("cannot write `{}`: {e}", path.display());
            return ExitCode::FAILURE;
        }
        println!(
            "{}: M = {}, n = {n} (uncondensed {}), {} instances -> {}",
            preset.name,
            qps.horizon(),
            doc["sparse"]["n"],
            qps.instances.len(),
            path.display()
        );
    }
    ExitCode::SUCCESS
}
