//! The Rust artefact: a Cargo package with the generated `static` data, the vendored
//! `mhe-embedded` crate (so the artefact builds outside this workspace) and the replay
//! program.

use std::fmt::Write as _;

use super::extract::{OwnedMpc, OwnedProblem, OwnedStructured, OwnedWindow};
use super::{Header, ScalarKind};

/// The vendored crate's files (path in the artefact, content).
pub(crate) const VENDORED: [(&str, &str); 9] = [
    (
        "mhe-embedded/src/lib.rs",
        include_str!("../vendor/mhe-embedded/src/lib.rs"),
    ),
    (
        "mhe-embedded/src/data.rs",
        include_str!("../vendor/mhe-embedded/src/data.rs"),
    ),
    (
        "mhe-embedded/src/estimator.rs",
        include_str!("../vendor/mhe-embedded/src/estimator.rs"),
    ),
    (
        "mhe-embedded/src/mpc.rs",
        include_str!("../vendor/mhe-embedded/src/mpc.rs"),
    ),
    (
        "mhe-embedded/src/qp.rs",
        include_str!("../vendor/mhe-embedded/src/qp.rs"),
    ),
    (
        "mhe-embedded/src/runtime.rs",
        include_str!("../vendor/mhe-embedded/src/runtime.rs"),
    ),
    (
        "mhe-embedded/src/scalar.rs",
        include_str!("../vendor/mhe-embedded/src/scalar.rs"),
    ),
    (
        "mhe-embedded/src/structured.rs",
        include_str!("../vendor/mhe-embedded/src/structured.rs"),
    ),
    (
        "mhe-embedded/Cargo.toml",
        "[package]\nname = \"mhe-embedded\"\nversion = \"0.1.0\"\nedition = \"2021\"\n\
         license = \"MIT OR Apache-2.0\"\npublish = false\n\n[dependencies]\n",
    ),
];

fn real(s: ScalarKind) -> &'static str {
    match s {
        ScalarKind::F64 => "f64",
        ScalarKind::F32 => "f32",
    }
}

/// A Rust literal of `v` in the artefact's scalar (shortest round-trip digits in that type).
fn literal(v: f64, s: ScalarKind) -> String {
    let r = real(s);
    match s {
        ScalarKind::F64 if v.is_infinite() => {
            format!("{}{r}::INFINITY", if v < 0.0 { "-" } else { "" })
        }
        ScalarKind::F64 => format!("{v:e}"),
        ScalarKind::F32 => {
            let f = v as f32;
            if f.is_infinite() {
                format!("{}{r}::INFINITY", if f < 0.0 { "-" } else { "" })
            } else {
                format!("{f:e}")
            }
        }
    }
}

fn array(out: &mut String, name: &str, v: &[f64], s: ScalarKind) -> String {
    let _ = write!(out, "static {name}: [Real; {}] = [", v.len());
    for (i, x) in v.iter().enumerate() {
        if i % 6 == 0 {
            out.push_str("\n    ");
        }
        out.push_str(&literal(*x, s));
        out.push_str(", ");
    }
    out.push_str("\n];\n");
    format!("&{name}")
}

/// The plant blocks every structured window shares (`STRUCTURED_A`, …), written once.
fn structured_shared(out: &mut String, st: &OwnedStructured, s: ScalarKind) {
    for (name, v) in [
        ("STRUCTURED_A", &st.a),
        ("STRUCTURED_E", &st.e),
        ("STRUCTURED_C", &st.c),
        ("STRUCTURED_F", &st.f),
        ("STRUCTURED_Q", &st.q),
        ("STRUCTURED_R", &st.r),
    ] {
        array(out, name, v, s);
    }
}

/// Window `prefix`'s structured factors (its 4η^m P and η^{m−1−j}; the shared blocks by
/// name) as a `static {prefix}_STRUCTURED`, and the `structured` field's value.
fn structured(
    out: &mut String,
    prefix: &str,
    st: Option<&OwnedStructured>,
    s: ScalarKind,
) -> String {
    let Some(st) = st else {
        return "None".into();
    };
    let p = array(out, &format!("{prefix}_STRUCTURED_P"), &st.p, s);
    let decay = array(out, &format!("{prefix}_STRUCTURED_DECAY"), &st.decay, s);
    let order = match st.order {
        mhe_embedded::SumOrder::Fixed => "Fixed",
        mhe_embedded::SumOrder::RunTime => "RunTime",
    };
    let _ = writeln!(
        out,
        "static {prefix}_STRUCTURED: Structured<'static, Real> = Structured {{ nx: {}, ny: {}, \
         nw1: {}, nw2: {}, order: SumOrder::{order}, a: &STRUCTURED_A, e: &STRUCTURED_E, \
         c: &STRUCTURED_C, f: &STRUCTURED_F, q: &STRUCTURED_Q, r: &STRUCTURED_R, p: {p}, \
         decay: {decay} }};",
        st.nx, st.ny, st.nw1, st.nw2
    );
    format!("Some(&{prefix}_STRUCTURED)")
}

/// The arrays of one QP (named `{prefix}_H`, …) and its `Window` literal.
fn window(out: &mut String, prefix: &str, w: &OwnedWindow, s: ScalarKind) -> String {
    let name = |f: &str| format!("{prefix}_{f}");
    let st = structured(out, prefix, w.structured.as_ref(), s);
    let h = array(out, &name("H"), &w.h, s);
    let m_rho = array(out, &name("M_RHO"), &w.m_rho, s);
    let m_inv = array(out, &name("M_INV"), &w.m_inv, s);
    let q0 = array(out, &name("Q0"), &w.q0, s);
    let f = array(out, &name("F"), &w.f, s);
    let lo = array(out, &name("LOWER"), &w.lower, s);
    let hi = array(out, &name("UPPER"), &w.upper, s);
    let d = array(out, &name("SCALING"), &w.scaling, s);
    format!(
        "Window {{ n: {}, n_theta: {}, h: {h}, m_rho: {m_rho}, m_inv: {m_inv}, q0: {q0}, \
         f: {f}, lower: {lo}, upper: {hi}, scaling: {d}, step: {}, momentum: {}, \
         inv_rho: {}, relaxation: {}, structured: {st} }}",
        w.n,
        w.n_theta,
        literal(w.step, s),
        literal(w.momentum, s),
        literal(w.inv_rho, s),
        literal(w.relaxation, s),
    )
}

fn method_rs(m: mhe_embedded::Method) -> &'static str {
    match m {
        mhe_embedded::Method::Pg => "Pg",
        mhe_embedded::Method::Fista => "Fista",
        mhe_embedded::Method::Admm => "Admm",
    }
}

/// `src/data.rs`.
pub(crate) fn data_rs(p: &OwnedProblem, mpc: Option<&OwnedMpc>, a: &Header) -> String {
    let s = a.scalar;
    let mut out = format!(
        "// Generated by `cargo xtask export` — do not edit.\n{}\n\
         #![allow(clippy::all, clippy::excessive_precision)]\n\n\
         #[allow(unused_imports)]\nuse mhe_embedded::{{Method, MpcProblem, Problem, Structured, SumOrder, WarmStart, Window}};\n\n\
         /// The scalar of this export.\npub type Real = {};\n\n",
        a.banner("// "),
        real(s)
    );
    let _ = writeln!(
        out,
        "/// n_x, n_u, n_y, M, n_z and n_θ of the full window, K.\n\
         pub const NX: usize = {};\npub const NU: usize = {};\npub const NY: usize = {};\n\
         pub const M: usize = {};\npub const NZ: usize = {};\npub const NTH: usize = {};\n\
         pub const K: usize = {};\n/// Whether K is certified (Theorem 1) for this method.\n\
         pub const CERTIFIED: bool = {};\n",
        p.nx,
        p.nu,
        p.ny,
        p.horizon,
        p.nz(),
        p.ntheta(),
        p.iterations,
        a.certified
    );
    let prior = a.prior.iter().map(|v| literal(*v, s)).collect::<Vec<_>>();
    let _ = writeln!(
        out,
        "/// The scenario's prior x̄₀ (`simulation.prior`).\npub const PRIOR: [Real; NX] = [{}];\n",
        prior.join(", ")
    );
    let ma = array(&mut out, "MODEL_A", &p.a, s);
    let mb = array(&mut out, "MODEL_B", &p.b, s);
    let me = array(&mut out, "MODEL_E", &p.e, s);
    if let Some(st) = p.windows.iter().find_map(|w| w.structured.as_ref()) {
        structured_shared(&mut out, st, s);
    }
    let mut windows = Vec::new();
    for (m, w) in p.windows.iter().enumerate() {
        windows.push(format!("    {}", window(&mut out, &format!("W{m}"), w, s)));
    }
    let _ = writeln!(
        out,
        "\nstatic WINDOWS: [Window<'static, Real>; {}] = [\n{}\n];\n",
        windows.len(),
        windows.join(",\n")
    );
    let method = method_rs(p.method);
    let warm = match p.warm_start {
        mhe_embedded::WarmStart::Paper => "Paper",
        mhe_embedded::WarmStart::Shifted => "Shifted",
    };
    let _ = writeln!(
        out,
        "/// The exported problem.\npub static PROBLEM: Problem<'static, Real> = Problem {{\n    \
         nx: {}, nu: {}, ny: {}, nw1: {}, nw2: {}, horizon: {}, iterations: {},\n    \
         method: Method::{method}, warm_start: WarmStart::{warm},\n    \
         a: {ma}, b: {mb}, e: {me}, windows: &WINDOWS,\n}};",
        p.nx, p.nu, p.ny, p.nw1, p.nw2, p.horizon, p.iterations
    );
    match (mpc, &a.mpc) {
        (Some(m), Some(am)) => {
            let _ = writeln!(
                out,
                "\n/// The K_c-iteration MPC: N, N n_u, K_c, whether (K, K_c) is certified (joint \
                 certificate).\npub const MPC_N: usize = {};\npub const MPC_NSEQ: usize = {};\n\
                 pub const MPC_KC: usize = {};\npub const MPC_CERTIFIED: bool = {};\n",
                m.horizon,
                m.nseq(),
                m.iterations,
                am.certified
            );
            let qp = window(&mut out, "MPC", &m.qp, s);
            let _ = writeln!(
                out,
                "\n/// The exported MPC.\npub static MPC: MpcProblem<'static, Real> = MpcProblem {{\n    \
                 nx: {}, nu: {}, horizon: {}, iterations: {}, method: Method::{},\n    qp: {qp},\n}};",
                m.nx,
                m.nu,
                m.horizon,
                m.iterations,
                method_rs(m.method)
            );
        }
        _ => {
            let _ = writeln!(
                out,
                "\n/// No MPC in this export (`cargo xtask export --kc`).\npub const MPC_NSEQ: usize = 1;"
            );
        }
    }
    out
}

/// `src/lib.rs`.
pub(crate) fn lib_rs(a: &Header) -> String {
    let controller = if a.mpc.is_some() {
        "/// The MPC at its first call (cold start); None only if the data do not fit.\n\
         pub fn controller() -> Option<Controller> {\n    Controller::new(&data::MPC).ok()\n}\n"
    } else {
        "/// None: this export has no MPC (`cargo xtask export --kc`).\n\
         pub fn controller() -> Option<Controller> {\n    None\n}\n"
    };
    let guard = if a.loop_certified() {
        ""
    } else {
        "\n#[cfg(not(feature = \"allow-uncertified\"))]\ncompile_error!(\"this export is \
         UNCERTIFIED (see certificate.json); build with `--features allow-uncertified` to use \
         it anyway\");\n"
    };
    format!(
        "//! The exported estimator (generated by `cargo xtask export` — do not edit).\n//!\n{}\n\
         #![no_std]\n{guard}\npub mod data;\n\npub use mhe_embedded;\n\n\
         /// The estimator type of this export (every buffer sized at compile time).\n\
         pub type Estimator = mhe_embedded::Mhe<'static, data::Real, {{ data::NX }}, {{ data::NU }}, \
         {{ data::NY }}, {{ data::M }}, {{ data::NZ }}, {{ data::NTH }}>;\n\n\
         /// The estimator at t = 0 with the scenario's prior.\n\
         pub fn estimator() -> Result<Estimator, mhe_embedded::DataError> {{\n    \
         Estimator::new(&data::PROBLEM, data::PRIOR)\n}}\n\n\
         /// The K_c-iteration MPC type of this export.\n\
         pub type Controller = mhe_embedded::Mpc<'static, data::Real, {{ data::NX }}, {{ data::NU }}, \
         {{ data::MPC_NSEQ }}>;\n\n{controller}",
        a.banner("//! ")
    )
}

/// The C ABI crate `capi/` (a `no_std` static library over the export) and its header.
const CAPI_LIB_RS: &str = include_str!("capi/lib.rs");
const CAPI_HEADER: &str = include_str!("capi/mhe_capi.h");

/// The checked-in C ABI source or header (f64) for the export's scalar: an f32 export gets
/// `mhe_capi_f32_*` symbols on `float`, so a header and a library of different scalars do
/// not link.
fn for_scalar(text: &str, s: ScalarKind) -> String {
    match s {
        ScalarKind::F64 => text.to_string(),
        ScalarKind::F32 => text
            .replace("mhe_capi_f64_", "mhe_capi_f32_")
            .replace("typedef double mhe_real;", "typedef float mhe_real;")
            .replace(
                "const SCALAR_BYTES: usize = 8;",
                "const SCALAR_BYTES: usize = 4;",
            ),
    }
}

/// `capi/src/lib.rs`.
pub(crate) fn capi_lib_rs(s: ScalarKind) -> String {
    for_scalar(CAPI_LIB_RS, s)
}

/// `capi/mhe_capi.h`.
pub(crate) fn capi_header(s: ScalarKind) -> String {
    for_scalar(CAPI_HEADER, s)
}
/// The C ABI's replay program.
pub(crate) const CAPI_REPLAY_C: &str = include_str!("capi/replay_capi.c");
pub(crate) const CAPI_LOOP_C: &str = include_str!("capi/loop_capi.c");

/// `capi/Cargo.toml`.
pub(crate) fn capi_cargo_toml(package: &str) -> String {
    format!(
        "# Generated by `cargo xtask export`: the C ABI (static library) of the export.\n\
         [package]\nname = \"{package}-capi\"\nversion = \"0.1.0\"\nedition = \"2021\"\n\
         publish = false\n\n[lib]\ncrate-type = [\"staticlib\"]\npath = \"src/lib.rs\"\n\n\
         [dependencies]\n{package} = {{ path = \"..\" }}\n\n\
         [features]\nallow-uncertified = [\"{package}/allow-uncertified\"]\n\n\
         [profile.dev]\npanic = \"abort\"\n\n[profile.release]\npanic = \"abort\"\n\n\
         # Not part of any enclosing workspace.\n[workspace]\n"
    )
}

/// The strict line reader of the replay and loop programs: exactly `count` finite numbers
/// per line, comma-separated; a line that is not UTF-8 or cannot be read is an error naming
/// it (never a silent end of input).
const INPUT_RS: &str = r#"/// Reads stdin line by line, strictly.
struct Input {
    lock: std::io::StdinLock<'static>,
    buf: Vec<u8>,
    lineno: usize,
}

impl Input {
    fn new() -> Self {
        Self { lock: std::io::stdin().lock(), buf: Vec::new(), lineno: 0 }
    }

    /// The next non-blank line's numbers with its 1-based number; None at the end.
    fn next(&mut self, count: usize, what: &str) -> Result<Option<(usize, Vec<f64>)>, String> {
        loop {
            self.buf.clear();
            self.lineno += 1;
            let n = self.lineno;
            match self.lock.read_until(b'\n', &mut self.buf) {
                Ok(0) => return Ok(None),
                Ok(_) => {}
                Err(e) => return Err(format!("line {n}: cannot read the input: {e}")),
            }
            let Ok(line) = std::str::from_utf8(&self.buf) else {
                return Err(format!("line {n}: not valid UTF-8"));
            };
            if line.trim().is_empty() {
                continue;
            }
            let vals: Option<Vec<f64>> = line
                .split(',')
                .map(|s| s.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect();
            return match vals {
                Some(v) if v.len() == count => Ok(Some((n, v))),
                _ => Err(format!(
                    "line {n}: expected exactly {count} finite numbers ({what}), comma-separated"
                )),
            };
        }
    }
}
"#;

/// `src/bin/loop.rs` (std: reads y per line, prints x̂ and u with 17 significant digits).
pub(crate) fn loop_rs(crate_name: &str) -> String {
    let krate = crate_name.replace('-', "_");
    format!(
        r#"//! The certified loop (generated by `cargo xtask export`): prints x̂_{{0|0}} and
//! u_0 = π(x̂_{{0|0}}) on one line, then for every input line "y_1,…,y_ny" (trace.csv's y
//! columns, row t) pushes (u_t, y_t), estimates x̂_{{t+1|t+1}}, computes u_{{t+1}} and
//! prints "x̂…,u…": output line t is row t of trace.csv's xhat and u columns (17
//! significant digits, comma-separated).
use std::io::{{BufRead, Write}};

{input}
use {krate}::data::{{NY, Real}};

fn print(out: &mut impl Write, x: &[Real], u: &[Real]) -> std::io::Result<()> {{
    let cols: Vec<String> = x.iter().chain(u).map(|v| format!("{{:.16e}}", f64::from(*v))).collect();
    writeln!(out, "{{}}", cols.join(","))
}}

fn main() -> std::process::ExitCode {{
    let fail = |msg: String| {{
        eprintln!("loop: {{msg}}");
        std::process::ExitCode::FAILURE
    }};
    let mut est = match {krate}::estimator() {{
        Ok(e) => e,
        Err(e) => return fail(format!("the exported data do not fit the estimator: {{e}}")),
    }};
    let Some(mut ctrl) = {krate}::controller() else {{
        return fail("this export has no MPC (cargo xtask export --kc K|certified)".into());
    }};
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let x = *est.estimate();
    let mut u = match ctrl.control(&x) {{
        Ok(u) => *u,
        Err(e) => return fail(format!("step 0: {{e}}")),
    }};
    let mut ok = print(&mut out, &x, &u).is_ok();
    let mut y = [0.0 as Real; NY];
    let mut input = Input::new();
    loop {{
        let (lineno, vals) = match input.next(NY, "y") {{
            Ok(Some(v)) => v,
            Ok(None) => break,
            Err(msg) => return fail(msg),
        }};
        let row = lineno - 1;
        for (i, x) in vals.iter().enumerate() {{
            y[i] = *x as Real;
        }}
        if let Err(e) = est.push(&u, &y) {{
            return fail(format!("line {{lineno}}: refused: {{e}}"));
        }}
        let x = *est.estimate();
        u = match ctrl.control(&x) {{
            Ok(u) => *u,
            Err(e) => return fail(format!("step {{}}: {{e}}", row + 1)),
        }};
        ok &= print(&mut out, &x, &u).is_ok();
    }}
    ok &= out.flush().is_ok();
    if ok {{ std::process::ExitCode::SUCCESS }} else {{ std::process::ExitCode::FAILURE }}
}}
"#,
        input = INPUT_RS
    )
}

/// `Cargo.toml`.
pub(crate) fn cargo_toml(package: &str) -> String {
    format!(
        "# Generated by `cargo xtask export`.\n[package]\nname = \"{package}\"\nversion = \"0.1.0\"\n\
         edition = \"2021\"\npublish = false\n\n[dependencies]\nmhe-embedded = {{ path = \"mhe-embedded\" }}\n\n\
         [[bin]]\nname = \"replay\"\npath = \"src/bin/replay.rs\"\n\n\
         [[bin]]\nname = \"loop\"\npath = \"src/bin/loop.rs\"\n\n\
         [features]\n# Builds an UNCERTIFIED export (src/lib.rs stops at compile_error! otherwise).\n\
         allow-uncertified = []\n\n\
         # Not part of any enclosing workspace.\n[workspace]\n"
    )
}

/// `src/bin/replay.rs` (std: reads stdin, prints 17 significant digits).
pub(crate) fn replay_rs(crate_name: &str) -> String {
    let krate = crate_name.replace('-', "_");
    format!(
        r#"//! Replay (generated by `cargo xtask export`): prints x̂_{{0|0}}, then for every input line
//! "u_1,…,u_nu,y_1,…,y_ny" (a row of trace.csv's u and y columns) pushes (u_t, y_t) and
//! prints x̂_{{t+1|t+1}}: output line t is row t of trace.csv's xhat columns (17 significant
//! digits, comma-separated).
use std::io::{{BufRead, Write}};

{input}
use {krate}::data::{{NU, NY, Real}};

fn print(out: &mut impl Write, x: &[Real]) -> std::io::Result<()> {{
    let cols: Vec<String> = x.iter().map(|v| format!("{{:.16e}}", f64::from(*v))).collect();
    writeln!(out, "{{}}", cols.join(","))
}}

fn main() -> std::process::ExitCode {{
    let mut est = match {krate}::estimator() {{
        Ok(e) => e,
        Err(e) => {{
            eprintln!("replay: the exported data do not fit the estimator: {{e}}");
            return std::process::ExitCode::FAILURE;
        }}
    }};
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut ok = print(&mut out, est.estimate()).is_ok();
    let (mut u, mut y) = ([0.0 as Real; NU], [0.0 as Real; NY]);
    let mut input = Input::new();
    loop {{
        let (lineno, vals) = match input.next(NU + NY, "u then y") {{
            Ok(Some(v)) => v,
            Ok(None) => break,
            Err(msg) => {{
                eprintln!("replay: {{msg}}");
                return std::process::ExitCode::FAILURE;
            }}
        }};
        for (i, x) in vals.iter().enumerate() {{
            if i < NU {{ u[i] = *x as Real }} else {{ y[i - NU] = *x as Real }}
        }}
        if let Err(e) = est.push(&u, &y) {{
            eprintln!("replay: line {{lineno}}: refused: {{e}}");
            return std::process::ExitCode::FAILURE;
        }}
        ok &= print(&mut out, est.estimate()).is_ok();
    }}
    ok &= out.flush().is_ok();
    if ok {{ std::process::ExitCode::SUCCESS }} else {{ std::process::ExitCode::FAILURE }}
}}
"#,
        input = INPUT_RS
    )
}
