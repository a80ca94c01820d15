//! A library outcome written in the certificate schema: which certificate covers a
//! configuration, and the encodings a reader of certificate.json relies on.

use certificate_json::v1;
use iss_certificate::coverage::{CertificateKind, Coverage};

fn main() -> Result<(), serde_json::Error> {
    let covered = Coverage::Covered(CertificateKind::Theorem1);
    // `From<&library type>`: the record owns the keys and encodings (v1), not the library.
    let record = v1::Coverage::from(&covered);
    println!("{}", serde_json::to_string(&record)?);
    println!("NaN → {}", serde_json::to_string(&v1::num(f64::NAN))?);
    println!(
        "{} v{}",
        v1::CERTIFICATE_FORMAT,
        v1::CERTIFICATE_FORMAT_VERSION
    );
    Ok(())
}
