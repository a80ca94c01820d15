//! How an entry point names a bad value (issue 38): every check is written once, against the
//! scenario file's keys (`mhe.eta`), and raises [`ModelError::Scenario`]; a Rust entry point
//! (a builder's `build`) re-labels that one error with its table of Rust items
//! ([`ModelError::for_rust`]), so its caller reads the method it called
//! (`MheBuilder::eta`) in a [`ModelError::Invalid`], and the file path keeps the key.
//!
//! ```
//! use lti_model::ModelError;
//! use lti_model::spec::{key_error, names::PLANT_NAMES};
//! let e = key_error("plant.a", "is unstable; pre-stabilise `plant.a` or shorten the horizon");
//! let rust = e.for_rust(&[&PLANT_NAMES]);
//! assert_eq!(rust.to_string(), "LtiSystem::a: is unstable; pre-stabilise `LtiSystem::a` or shorten the horizon");
//! assert!(matches!(rust, ModelError::Invalid { .. }));
//! ```

use crate::ModelError;

/// A table of (scenario key or `[section]`, Rust item) pairs.
pub type Names = [(&'static str, &'static str)];

/// The plant's keys: the matrices of [`crate::LtiSystem::new`] / [`crate::LtiSystem::with_disturbance`].
pub const PLANT_NAMES: [(&str, &str); 5] = [
    ("plant.a", "LtiSystem::a"),
    ("plant.b", "LtiSystem::b"),
    ("plant.c", "LtiSystem::c"),
    ("plant.e", "LtiSystem::e"),
    ("plant.f", "LtiSystem::f"),
];

/// The scenario's TOML-only hint (a scalar written for s·I), which a Rust caller cannot use.
const FILE_HINTS: [&str; 1] = [" (a positive number s gives s·I)"];

/// Is `c` part of a key (so `mhe.p` is not found inside `mhe.prior`)?
fn key_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// `text` with every whole occurrence of `key` replaced by `rust`.
fn replace_key(text: &str, key: &str, rust: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find(key) {
        let (head, tail) = rest.split_at(i);
        let after = &tail[key.len()..];
        let whole = !head.chars().next_back().is_some_and(key_char)
            && !after.chars().next().is_some_and(key_char);
        out.push_str(head);
        out.push_str(if whole { rust } else { key });
        rest = after;
    }
    out.push_str(rest);
    out
}

/// The Rust item of a scenario key: the longest key of `tables` that `key` starts with (a
/// longer key such as `sets.input.lower` keeps its tail; of equal keys, the first table's);
/// a key in no table is kept.
pub fn rust_field(key: &str, tables: &[&Names]) -> String {
    // The longest key; between equal keys the first table's (`fold` keeps the first).
    let best = tables
        .iter()
        .flat_map(|t| t.iter())
        .filter(|(k, _)| {
            key.strip_prefix(k)
                .is_some_and(|tail| tail.is_empty() || tail.starts_with('.'))
        })
        .fold(None::<&(&str, &str)>, |best, e| match best {
            Some(b) if b.0.len() >= e.0.len() => Some(b),
            _ => Some(e),
        });
    match best {
        Some((k, rust)) => format!("{rust}{}", &key[k.len()..]),
        None => key.to_string(),
    }
}

/// `text` with every scenario key and `[section]` of `tables` replaced by its Rust item (the
/// first table that names a key wins), the file format's hints dropped, and a hint
/// ``e.g. `iterations = 50` `` written as the builder call ``e.g. `.iterations(50)` ``.
pub fn rust_text(text: &str, tables: &[&Names]) -> String {
    let mut out = text.to_string();
    for hint in FILE_HINTS {
        out = out.replace(hint, "");
    }
    if let Some((head, tail)) = out.split_once("e.g. `")
        && let Some((assignment, rest)) = tail.split_once('`')
        && let Some((name, value)) = assignment.split_once(" = ")
        && !name.contains('.')
    {
        out = format!("{head}e.g. `.{name}({value})`{rest}");
    }
    for table in tables {
        for (key, rust) in table.iter() {
            out = replace_key(&out, key, rust);
        }
    }
    out
}

impl ModelError {
    /// This error as a Rust entry point reports it: a [`ModelError::Scenario`] becomes a
    /// [`ModelError::Invalid`] naming the Rust item of its key (and of every key its
    /// message names) from `tables`; the name of a shape, finiteness, weight or set error is
    /// renamed the same way; every other error is kept.
    #[must_use]
    pub fn for_rust(self, tables: &[&Names]) -> Self {
        let name = |n: String| {
            if n.contains('.') {
                rust_field(&n, tables)
            } else {
                n
            }
        };
        match self {
            Self::Scenario { key, problem } => Self::Invalid {
                field: rust_field(&key, tables),
                problem: rust_text(&problem, tables),
            },
            Self::Shape {
                name: n,
                expected_rows,
                expected_cols,
                actual_rows,
                actual_cols,
            } => Self::Shape {
                name: name(n),
                expected_rows,
                expected_cols,
                actual_rows,
                actual_cols,
            },
            Self::NonFinite {
                name: n,
                row,
                col,
                value,
            } => Self::NonFinite {
                name: name(n),
                row,
                col,
                value,
            },
            Self::NotSymmetric { name: n, asymmetry } => Self::NotSymmetric {
                name: name(n),
                asymmetry,
            },
            Self::NotPositiveDefinite {
                name: n,
                min_eigenvalue,
            } => Self::NotPositiveDefinite {
                name: name(n),
                min_eigenvalue,
            },
            Self::InvalidSet { name: n, reason } => Self::InvalidSet {
                name: name(n),
                reason,
            },
            other => other,
        }
    }
}
