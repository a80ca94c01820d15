//! Version 1 of the certificate JSON: plain serde records whose field order and encodings
//! are the schema (docs/certificate-json.md).
//!
//! Every record mirrors one library outcome type and is built from it with `From<&T>`; the
//! library types carry no serde derives of their own (their `serde` feature is off), so a
//! field added to a library type changes nothing here until this module maps it. Adding a
//! key here is an additive change (a new minor version of the documents' readers' contract,
//! same `format_version`); removing or re-encoding one needs a `v2` module.
//!
//! Encodings: a float that is not finite (NaN as "no value", ±∞) is written as `null`
//! ([`num`]); the typed outcome reasons (void reasons, IOSS failures, skip reasons) are
//! written as their `Display` sentence; the document records (`Certificate`,
//! `IossCertificate`, runs, provenance) are filled by the tool that writes them.

mod documents;
mod from_library;
mod method;
mod outcomes;
mod trace;
mod trace_steps;

pub use documents::*;
pub use method::Method;
pub use outcomes::*;
pub use trace::*;
pub use trace_steps::*;

/// `format` of `certificate.json` (`cargo xtask reproduce`).
pub const CERTIFICATE_FORMAT: &str = "suboptimal-mhe/closed-loop-certificate";
/// `format_version` of `certificate.json` in this schema.
pub const CERTIFICATE_FORMAT_VERSION: u32 = 1;
/// `format` of the IOSS certificate (`cargo xtask certify`).
pub const IOSS_FORMAT: &str = "suboptimal-mhe/ioss-certificate";
/// `format_version` of the IOSS certificate in this schema.
pub const IOSS_FORMAT_VERSION: u32 = 2;

/// A float as JSON: `null` unless finite (the library's "no value" NaN and ±∞ alike; what
/// `serde_json` writes for them, made explicit so an `Option<f64>` field reads the same).
pub fn num(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

#[cfg(test)]
mod tests;
