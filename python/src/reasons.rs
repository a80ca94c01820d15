//! Void, IOSS and skip reasons as data (`iss_certificate::outcome`'s enums): one JSON object
//! per reason, `kind` (the variant, snake_case), its fields, and `text`, the sentence the
//! CLI prints (the enum's `Display`, as certificate.json carries it). Python wraps each as a
//! `Reason`, so a caller matches `reason.kind`, never the text.

use iss_certificate::certificate::ClosedLoopCertificate;
use iss_certificate::outcome::{IossFailure, SkipReason, VoidReason};
use qp_iter::Method;
use serde_json::{Value, json};

/// `{kind, …fields, text}` of one void reason.
pub(crate) fn void_reason(r: &VoidReason) -> Value {
    let mut v = match r {
        VoidReason::LPhiUndefined { reason } => {
            json!({"kind": "l_phi_undefined", "reason": reason})
        }
        VoidReason::ControllerUndefined { reason } => {
            json!({"kind": "controller_undefined", "reason": reason})
        }
        VoidReason::PremiseFails {
            premise,
            needed_by,
            value,
            fix,
        } => json!({"kind": "premise_fails", "premise": premise, "needed_by": needed_by,
                    "value": value,
                    "fix": fix.as_ref().map_or_else(String::new, ToString::to_string)}),
        VoidReason::PremiseNotEvaluated { premise, because } => {
            // NotEvaluated serialises as its sentence (as in certificate.json).
            json!({"kind": "premise_not_evaluated", "premise": premise,
                   "because": because.to_string()})
        }
        VoidReason::Gamma13 { premise, void } => {
            // Gamma13Void serialises with its own `kind` tag: kept as `void`, in
            // certificate.json's schema (certificate_json::v1), as the CLI writes it.
            json!({"kind": "gamma13", "premise": premise,
                   "void": certificate_json::v1::Gamma13Void::from(void)})
        }
        VoidReason::NoK { k_max } => json!({"kind": "no_k", "k_max": k_max}),
        VoidReason::NoPair {
            k_max,
            spectral_radius,
        } => json!({"kind": "no_pair", "k_max": k_max, "spectral_radius": spectral_radius}),
        VoidReason::BoundaryCut { max_corners } => {
            json!({"kind": "boundary_cut", "max_corners": max_corners})
        }
        _ => json!({"kind": "other"}),
    };
    v["text"] = Value::String(r.to_string());
    v
}

/// `{kind, …fields, text}` of one skip reason.
pub(crate) fn skip_reason(r: &SkipReason) -> Value {
    let mut v = match r {
        SkipReason::OverVariableCap {
            saturable,
            cap,
            depth,
        } => json!({"kind": "over_variable_cap", "saturable": saturable, "cap": cap,
                    "depth": depth}),
        SkipReason::OverBudget {
            saturable,
            metrics,
            n_x,
            work,
            seconds,
            budget_seconds,
            depth,
        } => json!({"kind": "over_budget", "saturable": saturable, "metrics": metrics,
                    "n_x": n_x, "work": work, "seconds": seconds,
                    "budget_seconds": budget_seconds, "depth": depth}),
        SkipReason::NoSequences {
            user_value_unchecked,
        } => json!({"kind": "no_sequences", "user_value_unchecked": user_value_unchecked}),
        _ => json!({"kind": "other"}),
    };
    v["text"] = Value::String(r.to_string());
    v
}

/// `{kind: "ioss_failure", error, text}`: LMI (2) failed (the model error's sentence).
pub(crate) fn ioss_failure(f: &IossFailure) -> Value {
    json!({"kind": "ioss_failure", "error": f.error.to_string(), "text": f.to_string()})
}

/// Every reason of `cert` as one JSON document: `void` per method (name → list), `ioss`
/// (object or null), `skipped` (γ₁,₃ computations not run: `computation` + the reason).
pub(crate) fn all(cert: &ClosedLoopCertificate) -> Value {
    let void: serde_json::Map<String, Value> = cert
        .solvers
        .iter()
        .map(|s| {
            let name = Method::name(&s.solver).into_owned();
            (name, s.void_reasons.iter().map(void_reason).collect())
        })
        .collect();
    let skipped: Vec<Value> = cert
        .gamma13
        .skipped
        .iter()
        .map(|s| {
            let mut v = skip_reason(&s.reason);
            v["computation"] = Value::String(s.computation.clone());
            v
        })
        .collect();
    json!({
        "void": void,
        "ioss": cert.ioss_failure.as_ref().map(ioss_failure),
        "skipped": skipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `text` is the Display sentence and the fields are the variant's.
    #[test]
    fn a_void_reason_carries_its_fields_and_the_cli_sentence() {
        let r = VoidReason::NoK { k_max: 1 << 24 };
        let v = void_reason(&r);
        assert_eq!(v["kind"], "no_k");
        assert_eq!(v["k_max"], 1 << 24);
        assert_eq!(v["text"], r.to_string());
    }
}
