//! Generated input files for the property tests of the library entry points
//! (`cli/generated_inputs.rs`) and of the `xtask` binary (`cli/generated_cli.rs`); `cli/main.rs`
//! and `survey.rs` include this file as a module: scenario TOML files and sweep configs, each
//! valid, almost valid (one key perturbed) or hostile (random bytes, cut text, deep nesting,
//! huge arrays).
//!
//! Plants are tiny (n_x ≤ 3, n_u, n_y ≤ 2, M, N ≤ 3, K ≤ 4, T ≤ 4) so that a case costs
//! milliseconds; a perturbation that asks for a large size asks for one beyond a limit
//! (refused before allocation) or one the test caps when it simulates.
#![allow(dead_code)]

use proptest::collection::vec;
use proptest::prelude::*;
use toml::{Table, Value};

/// The parameters of a valid tiny scenario.
#[derive(Debug, Clone)]
pub struct Base {
    pub nx: usize,
    pub nu: usize,
    pub ny: usize,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub c: Vec<f64>,
    pub e_scalar: Option<f64>,
    pub input_bound: Option<f64>,
    pub dist_bound: f64,
    pub noise: u8,
    pub seed: u64,
    pub x0: Vec<f64>,
    pub prior: Vec<f64>,
    pub steps: usize,
    pub m: usize,
    pub eta: f64,
    pub k: usize,
    pub method: u8,
    pub mhe_q: Option<f64>,
    pub n: usize,
    pub mpc_r: f64,
    pub gamma13: Option<f64>,
}

fn round(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

/// A valid tiny scenario: A scaled to ‖A‖_F = ρ < 1 (so stable), random B, C.
pub fn base() -> impl Strategy<Value = Base> {
    (1..=3usize, 1..=2usize, 1..=2usize)
        .prop_flat_map(|(nx, nu, ny)| {
            let mat = move |n: usize| vec(-1.0f64..1.0, n);
            (
                (Just((nx, nu, ny)), mat(nx * nx), mat(nx * nu), mat(ny * nx)),
                (
                    0.1f64..0.95,
                    prop::option::of(0.2f64..2.0),
                    prop::option::of(0.2f64..2.0),
                    0.01f64..0.3,
                    0u8..3,
                    any::<u64>(),
                ),
                (vec(-2.0f64..2.0, nx), vec(-2.0f64..2.0, nx), 1..=4usize),
                (
                    1..=3usize,
                    0.5f64..0.95,
                    1..=4usize,
                    0u8..4,
                    prop::option::of(0.2f64..3.0),
                ),
                (1..=3usize, 0.05f64..2.0, prop::option::of(1.0f64..100.0)),
            )
        })
        .prop_map(
            |(
                ((nx, nu, ny), a, b, c),
                (rho, e_scalar, input_bound, dist_bound, noise, seed),
                (x0, prior, steps),
                (m, eta, k, method, mhe_q),
                (n, mpc_r, gamma13),
            )| {
                let fro = a.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-9);
                Base {
                    nx,
                    nu,
                    ny,
                    a: a.iter().map(|v| round(v * rho / fro)).collect(),
                    b: b.into_iter().map(round).collect(),
                    c: c.into_iter().map(round).collect(),
                    e_scalar: e_scalar.map(round),
                    input_bound: input_bound.map(round),
                    dist_bound: round(dist_bound).max(0.01),
                    noise,
                    seed: seed >> 1,
                    x0: x0.into_iter().map(round).collect(),
                    prior: prior.into_iter().map(round).collect(),
                    steps,
                    m,
                    eta: round(eta),
                    k,
                    method,
                    mhe_q: mhe_q.map(round),
                    n,
                    mpc_r: round(mpc_r).max(0.05),
                    gamma13: gamma13.map(round),
                }
            },
        )
}

fn rows(v: &[f64], r: usize, c: usize) -> Value {
    Value::Array(
        (0..r)
            .map(|i| Value::Array((0..c).map(|j| Value::Float(v[i * c + j])).collect()))
            .collect(),
    )
}

fn floats(v: &[f64]) -> Value {
    Value::Array(v.iter().map(|x| Value::Float(*x)).collect())
}

fn table(pairs: Vec<(&str, Value)>) -> Value {
    Value::Table(pairs.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
}

/// The scenario of `b` as a TOML table.
pub fn scenario_table(b: &Base) -> Table {
    let mut t = Table::new();
    t.insert("name".into(), Value::String("generated".into()));
    let mut plant = vec![
        ("a", rows(&b.a, b.nx, b.nx)),
        ("b", rows(&b.b, b.nx, b.nu)),
        ("c", rows(&b.c, b.ny, b.nx)),
    ];
    if let Some(e) = b.e_scalar {
        plant.push(("e", Value::Float(e)));
    }
    t.insert("plant".into(), table(plant));
    let mut sets = vec![(
        "disturbance",
        table(vec![
            ("lower", Value::Float(-b.dist_bound)),
            ("upper", Value::Float(b.dist_bound)),
        ]),
    )];
    if let Some(u) = b.input_bound {
        sets.push((
            "input",
            table(vec![
                ("lower", floats(&vec![-u; b.nu])),
                ("upper", floats(&vec![u; b.nu])),
            ]),
        ));
    }
    t.insert("sets".into(), table(sets));
    let seed = Value::Integer((b.seed % (1 << 40)) as i64);
    let noise = match b.noise {
        0 => table(vec![
            ("kind", Value::String("uniform".into())),
            ("seed", seed),
        ]),
        1 => table(vec![
            ("kind", Value::String("gaussian".into())),
            ("covariance", Value::Float(0.001)),
            ("scale", Value::Float(1.0)),
            ("seed", seed),
        ]),
        _ => table(vec![("kind", Value::String("zero".into()))]),
    };
    t.insert("noise".into(), noise);
    t.insert(
        "simulation".into(),
        table(vec![
            ("x0", floats(&b.x0)),
            ("prior", floats(&b.prior)),
            ("steps", Value::Integer(b.steps as i64)),
        ]),
    );
    let method = ["pg", "fista", "admm", "admm-pr"][b.method as usize % 4];
    let mut mhe = vec![
        ("horizon", Value::Integer(b.m as i64)),
        ("eta", Value::Float(b.eta)),
        ("iterations", Value::Integer(b.k as i64)),
        ("method", Value::String(method.into())),
    ];
    if let Some(q) = b.mhe_q {
        mhe.push(("q", Value::Float(q)));
    }
    t.insert("mhe".into(), table(mhe));
    t.insert(
        "mpc".into(),
        table(vec![
            ("horizon", Value::Integer(b.n as i64)),
            ("r", Value::Float(b.mpc_r)),
        ]),
    );
    if let Some(g) = b.gamma13 {
        t.insert(
            "certificate".into(),
            table(vec![("gamma13", Value::Float(g))]),
        );
    }
    t
}

/// Every key of the scenario format (docs/scenario-format.md), present or not.
pub const SCENARIO_KEYS: &[&str] = &[
    "name",
    "description",
    "plant",
    "plant.a",
    "plant.b",
    "plant.c",
    "plant.e",
    "plant.f",
    "sets",
    "sets.state",
    "sets.input",
    "sets.output",
    "sets.disturbance",
    "sets.state.lower",
    "sets.input.upper",
    "sets.disturbance.lower",
    "sets.disturbance.upper",
    "noise",
    "noise.kind",
    "noise.scale",
    "noise.covariance",
    "noise.seed",
    "simulation",
    "simulation.x0",
    "simulation.prior",
    "simulation.steps",
    "mhe",
    "mhe.horizon",
    "mhe.eta",
    "mhe.iterations",
    "mhe.q",
    "mhe.r",
    "mhe.p",
    "mhe.method",
    "mhe.warm_start",
    "mpc",
    "mpc.horizon",
    "mpc.q",
    "mpc.r",
    "mpc.terminal",
    "certificate",
    "certificate.gamma13",
];

/// Keys whose value is a matrix or a vector (huge-entry and shape perturbations).
pub const ARRAY_KEYS: &[&str] = &[
    "plant.a",
    "plant.b",
    "plant.c",
    "plant.e",
    "plant.f",
    "simulation.x0",
    "simulation.prior",
    "mhe.q",
    "mhe.r",
    "mhe.p",
    "mpc.q",
    "mpc.r",
    "noise.covariance",
    "sets.input.upper",
    "sets.disturbance.lower",
];

/// Weights that must be symmetric positive definite.
pub const WEIGHT_KEYS: &[&str] = &[
    "mhe.q",
    "mhe.r",
    "mhe.p",
    "mpc.q",
    "mpc.r",
    "noise.covariance",
];

/// A bad value put in place of a key's value.
#[derive(Debug, Clone)]
pub enum Bad {
    Float(f64),
    Int(i64),
    Str(String),
    Bool(bool),
    EmptyArray,
    EmptyRows,
    EmptyTable,
    Flatten,
    ExtraRow,
    ExtraColumn,
    Ragged,
    DropRow,
    Strings,
    Datetime,
    /// One entry of the existing matrix or vector set to this value.
    Entry(usize, f64),
}

fn bad_float() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(1e308),
        Just(-1e300),
        Just(1e200),
        Just(1e101),
        Just(0.0),
        Just(-1.0),
        Just(-0.0),
        Just(5e-324),
        Just(1e-300),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        -1e3f64..1e3,
    ]
}

fn bad() -> impl Strategy<Value = Bad> {
    prop_oneof![
        bad_float().prop_map(Bad::Float),
        prop_oneof![
            Just(0i64),
            Just(-1),
            Just(i64::MAX),
            Just(i64::MIN),
            Just(1 << 40),
            -5i64..64
        ]
        .prop_map(Bad::Int),
        "[a-z\\- ]{0,8}".prop_map(Bad::Str),
        any::<bool>().prop_map(Bad::Bool),
        Just(Bad::EmptyArray),
        Just(Bad::EmptyRows),
        Just(Bad::EmptyTable),
        Just(Bad::Flatten),
        Just(Bad::ExtraRow),
        Just(Bad::ExtraColumn),
        Just(Bad::Ragged),
        Just(Bad::DropRow),
        Just(Bad::Strings),
        Just(Bad::Datetime),
        (0usize..9, bad_float()).prop_map(|(i, v)| Bad::Entry(i, v)),
    ]
}

/// One perturbation of a valid scenario.
#[derive(Debug, Clone)]
pub enum Edit {
    /// `SCENARIO_KEYS[key]` replaced by (or set to) a bad value.
    Replace(usize, Bad),
    /// `SCENARIO_KEYS[key]` removed.
    Remove(usize),
    /// An unknown key `zz…` in the section of `SCENARIO_KEYS[key]`.
    Unknown(usize, String),
    /// `mhe.eta` outside [0, 1).
    Eta(f64),
    /// `mhe.horizon`, `mpc.horizon`, `mhe.iterations`, `simulation.steps` (index 0..4) set.
    Count(usize, i64),
    /// A weight (`WEIGHT_KEYS[key]`) that is not positive definite: 0 negative scalar,
    /// 1 zero, 2 indefinite, 3 asymmetric, 4 singular diagonal.
    NonPd(usize, u8),
    /// E with a zero on its diagonal.
    SingularE(usize),
    /// A with the given factor (≥ 1.2: unstable).
    UnstableA(f64),
    /// One entry of `ARRAY_KEYS[key]` set to a huge value.
    Huge(usize, usize, f64),
    /// B with no columns.
    NoInputs,
    /// M so long that η^(M−1) underflows the strong-convexity floor.
    LongHorizon(u8),
    /// η = 0 (legal) with M ≥ 2.
    EtaZero,
    /// A bound excluding 0 or lower > upper.
    BadBox(u8),
    /// `mhe.method` with a bad table.
    BadMethod(u8, f64),
}

pub fn edit() -> impl Strategy<Value = Edit> {
    let nkeys = SCENARIO_KEYS.len();
    prop_oneof![
        6 => (0..nkeys, bad()).prop_map(|(k, b)| Edit::Replace(k, b)),
        2 => (0..nkeys).prop_map(Edit::Remove),
        1 => (0..nkeys, "zz[a-z]{1,6}").prop_map(|(k, n)| Edit::Unknown(k, n)),
        1 => prop_oneof![Just(1.0), Just(-0.1), Just(1.5), Just(f64::NAN), Just(0.999_999_9), Just(f64::INFINITY), 1.0f64..1e6].prop_map(Edit::Eta),
        2 => (0usize..4, prop_oneof![Just(0i64), Just(-1), Just(1_000_000), Just(i64::MAX), Just(100_001), Just(10_000_001), Just(1 << 33)]).prop_map(|(k, v)| Edit::Count(k, v)),
        1 => (0..WEIGHT_KEYS.len(), 0u8..5).prop_map(|(k, f)| Edit::NonPd(k, f)),
        1 => (0usize..3).prop_map(Edit::SingularE),
        1 => prop_oneof![1.2f64..3.0, 3.0f64..100.0, Just(1e50), Just(1e120)].prop_map(Edit::UnstableA),
        2 => (0..ARRAY_KEYS.len(), 0usize..9, prop_oneof![Just(1e308), Just(-1e300), Just(1e200), Just(1e160), Just(1e120), Just(f64::MAX)]).prop_map(|(k, i, v)| Edit::Huge(k, i, v)),
        1 => Just(Edit::NoInputs),
        1 => any::<u8>().prop_map(Edit::LongHorizon),
        1 => Just(Edit::EtaZero),
        1 => (0u8..4).prop_map(Edit::BadBox),
        1 => (0u8..4, prop_oneof![Just(0.0), Just(-1.0), Just(f64::NAN), Just(3.0), Just(1e300)]).prop_map(|(k, v)| Edit::BadMethod(k, v)),
    ]
}

fn get_mut<'a>(t: &'a mut Table, path: &str) -> Option<&'a mut Value> {
    let mut parts = path.split('.');
    let first = parts.next()?;
    let mut v = t.get_mut(first)?;
    for p in parts {
        v = v.as_table_mut()?.get_mut(p)?;
    }
    Some(v)
}

/// Sets `path` (creating the tables on the way; a non-table on the way is replaced).
fn set(t: &mut Table, path: &str, value: Value) {
    let parts: Vec<&str> = path.split('.').collect();
    let mut cur = t;
    for p in &parts[..parts.len() - 1] {
        let entry = cur
            .entry(p.to_string())
            .or_insert_with(|| Value::Table(Table::new()));
        if !entry.is_table() {
            *entry = Value::Table(Table::new());
        }
        cur = match entry.as_table_mut() {
            Some(t) => t,
            None => return,
        };
    }
    cur.insert(parts[parts.len() - 1].to_string(), value);
}

fn remove(t: &mut Table, path: &str) {
    match path.rsplit_once('.') {
        None => {
            t.remove(path);
        }
        Some((parent, last)) => {
            if let Some(Value::Table(p)) = get_mut(t, parent) {
                p.remove(last);
            }
        }
    }
}

fn float_of(v: &Value) -> f64 {
    match v {
        Value::Float(f) => *f,
        Value::Integer(i) => *i as f64,
        _ => 1.0,
    }
}

/// The current value of `path`, or a 2×2 identity-like matrix when absent.
fn current(t: &mut Table, path: &str) -> Value {
    get_mut(t, path)
        .cloned()
        .unwrap_or_else(|| rows(&[1.0, 0.0, 0.0, 1.0], 2, 2))
}

fn apply_bad(old: Value, bad: &Bad) -> Value {
    let arr = |v: &Value| v.as_array().cloned();
    match bad {
        Bad::Float(f) => Value::Float(*f),
        Bad::Int(i) => Value::Integer(*i),
        Bad::Str(s) => Value::String(s.clone()),
        Bad::Bool(b) => Value::Boolean(*b),
        Bad::EmptyArray => Value::Array(vec![]),
        Bad::EmptyRows => Value::Array(vec![Value::Array(vec![]), Value::Array(vec![])]),
        Bad::EmptyTable => Value::Table(Table::new()),
        Bad::Strings => Value::Array(vec![Value::String("1".into()), Value::String("x".into())]),
        Bad::Datetime => "1979-05-27T07:32:00Z"
            .parse::<toml::value::Datetime>()
            .map(Value::Datetime)
            .unwrap_or(Value::Boolean(true)),
        Bad::Flatten => match arr(&old) {
            Some(a) => Value::Array(
                a.into_iter()
                    .flat_map(|r| match r {
                        Value::Array(x) => x,
                        other => vec![other],
                    })
                    .collect(),
            ),
            None => Value::Array(vec![old]),
        },
        Bad::ExtraRow => match arr(&old) {
            Some(mut a) if !a.is_empty() => {
                let first = a[0].clone();
                a.push(first);
                Value::Array(a)
            }
            _ => Value::Array(vec![old.clone(), old]),
        },
        Bad::DropRow => match arr(&old) {
            Some(mut a) => {
                a.pop();
                Value::Array(a)
            }
            None => Value::Array(vec![]),
        },
        Bad::ExtraColumn | Bad::Ragged => match arr(&old) {
            Some(a) => {
                let ragged = matches!(bad, Bad::Ragged);
                Value::Array(
                    a.into_iter()
                        .enumerate()
                        .map(|(i, r)| match r {
                            Value::Array(mut x) if !ragged || i == 0 => {
                                x.push(Value::Float(0.5));
                                Value::Array(x)
                            }
                            other => other,
                        })
                        .collect(),
                )
            }
            None => old,
        },
        Bad::Entry(i, v) => set_entry(old, *i, *v),
    }
}

/// `old` with its `i`-th numeric entry (row-major, modulo the count) set to `v`; a scalar
/// becomes `v`, a `{ diagonal }` table gets it on the diagonal.
fn set_entry(old: Value, i: usize, v: f64) -> Value {
    fn count(v: &Value) -> usize {
        match v {
            Value::Array(a) => a.iter().map(count).sum(),
            Value::Table(t) => t.values().map(count).sum(),
            Value::Float(_) | Value::Integer(_) => 1,
            _ => 0,
        }
    }
    fn put(v: &mut Value, i: &mut usize, x: f64) -> bool {
        match v {
            Value::Array(a) => a.iter_mut().any(|e| put(e, i, x)),
            Value::Table(t) => t.iter_mut().any(|(_, e)| put(e, i, x)),
            Value::Float(_) | Value::Integer(_) => {
                if *i == 0 {
                    *v = Value::Float(x);
                    true
                } else {
                    *i -= 1;
                    false
                }
            }
            _ => false,
        }
    }
    let n = count(&old);
    if n == 0 {
        return Value::Float(v);
    }
    let mut out = old;
    let mut k = i % n;
    put(&mut out, &mut k, v);
    out
}

/// A weight at `key` (n × n for its n) that is not positive definite, in the `form`-th way:
/// a negative or zero scalar, a negative diagonal entry, an asymmetric matrix or a zero
/// diagonal entry.
fn non_pd(b: &Base, key: &str, form: u8) -> Value {
    let n = match key {
        "mhe.q" | "noise.covariance" => b.nx + b.ny,
        "mhe.r" => b.ny,
        "mpc.r" => b.nu,
        _ => b.nx,
    };
    match form {
        0 => Value::Float(-0.5),
        1 => Value::Float(0.0),
        2 => {
            let mut d = vec![1.0; n];
            d[n - 1] = -1.0;
            table(vec![("diagonal", floats(&d))])
        }
        3 if n >= 2 => {
            let mut m = vec![0.0; n * n];
            for i in 0..n {
                m[i * n + i] = 1.0;
            }
            m[1] = 0.5;
            rows(&m, n, n)
        }
        _ => {
            let mut d = vec![1.0; n];
            d[0] = 0.0;
            table(vec![("diagonal", floats(&d))])
        }
    }
}

/// Applies `edit` to the scenario table of `b`.
pub fn apply(b: &Base, edit: &Edit) -> Table {
    let mut t = scenario_table(b);
    match edit {
        Edit::Replace(k, bad) => {
            let key = SCENARIO_KEYS[*k];
            let old = current(&mut t, key);
            set(&mut t, key, apply_bad(old, bad));
        }
        Edit::Remove(k) => remove(&mut t, SCENARIO_KEYS[*k]),
        Edit::Unknown(k, name) => {
            let key = SCENARIO_KEYS[*k];
            let section = key.split('.').next().unwrap_or("");
            let path = if matches!(t.get(section), Some(Value::Table(_))) {
                format!("{section}.{name}")
            } else {
                name.clone()
            };
            set(&mut t, &path, Value::Integer(1));
        }
        Edit::Eta(v) => set(&mut t, "mhe.eta", Value::Float(*v)),
        Edit::Count(k, v) => {
            let key = [
                "mhe.horizon",
                "mpc.horizon",
                "mhe.iterations",
                "simulation.steps",
            ][*k];
            set(&mut t, key, Value::Integer(*v));
        }
        Edit::NonPd(k, form) => {
            let key = WEIGHT_KEYS[*k];
            if key == "noise.covariance" {
                set(&mut t, "noise.kind", Value::String("gaussian".into()));
            }
            set(&mut t, key, non_pd(b, key, *form));
        }
        Edit::SingularE(i) => {
            let mut d = vec![1.0; b.nx];
            d[i % b.nx] = 0.0;
            set(&mut t, "plant.e", table(vec![("diagonal", floats(&d))]));
        }
        Edit::UnstableA(f) => {
            let mut a = b.a.clone();
            a.iter_mut().for_each(|v| *v *= f);
            a[0] = *f;
            set(&mut t, "plant.a", rows(&a, b.nx, b.nx));
        }
        Edit::Huge(k, i, v) => {
            let key = ARRAY_KEYS[*k];
            let old = current(&mut t, key);
            set(&mut t, key, set_entry(old, *i, *v));
        }
        Edit::NoInputs => {
            set(
                &mut t,
                "plant.b",
                Value::Array((0..b.nx).map(|_| Value::Array(vec![])).collect()),
            );
            remove(&mut t, "sets.input");
        }
        Edit::LongHorizon(extra) => {
            // η^(M−1) ≤ 1e-13.
            let m = 2 + ((1e-13f64).ln() / b.eta.ln()).ceil() as i64 + (*extra % 8) as i64;
            set(&mut t, "mhe.horizon", Value::Integer(m));
        }
        Edit::EtaZero => {
            set(&mut t, "mhe.eta", Value::Float(0.0));
            set(&mut t, "mhe.horizon", Value::Integer(2));
        }
        Edit::BadBox(kind) => {
            let (l, u) = match kind {
                0 => (1.0, 2.0),
                1 => (1.0, -1.0),
                2 => (f64::INFINITY, f64::INFINITY),
                _ => (f64::NAN, 1.0),
            };
            set(
                &mut t,
                "sets.disturbance",
                table(vec![("lower", Value::Float(l)), ("upper", Value::Float(u))]),
            );
        }
        Edit::BadMethod(kind, v) => {
            let m = match kind {
                0 => table(vec![
                    ("method", Value::String("pg".into())),
                    ("step", Value::Float(*v)),
                ]),
                1 => table(vec![
                    ("method", Value::String("admm".into())),
                    ("rho", Value::Float(*v)),
                ]),
                2 => table(vec![
                    ("method", Value::String("admm".into())),
                    ("alpha", Value::Float(*v)),
                ]),
                _ => table(vec![("method", Value::String("newton".into()))]),
            };
            set(&mut t, "mhe.method", m);
        }
    }
    t
}

/// Hostile text: not a scenario at all, or one cut or blown up.
#[derive(Debug, Clone)]
pub enum Hostile {
    Bytes(Vec<u8>),
    /// A valid scenario cut after this fraction (per mille) of its bytes.
    Truncated(u16),
    DeepArrays(usize),
    DeepInline(usize),
    DeepHeader(usize),
    /// `key = [0, 0, …]` with this many entries (`ARRAY_KEYS[key]`).
    HugeArray(usize, usize),
    /// A square matrix of this size at `plant.a` (beyond the limits or just big).
    HugeMatrix(usize),
    /// `{ diagonal = [...] }` of this length at `mhe.q`.
    HugeDiagonal(usize),
    LongString(usize),
    ManyKeys(usize),
    /// A valid scenario with random printable garbage inserted at a position.
    Garbage(u16, String),
}

pub fn hostile() -> impl Strategy<Value = Hostile> {
    prop_oneof![
        3 => vec(any::<u8>(), 0..400).prop_map(Hostile::Bytes),
        3 => (0u16..1000).prop_map(Hostile::Truncated),
        1 => prop_oneof![Just(64usize), Just(200), Just(5_000), Just(20_000)].prop_map(Hostile::DeepArrays),
        1 => prop_oneof![Just(64usize), Just(200), Just(5_000), Just(20_000)].prop_map(Hostile::DeepInline),
        1 => prop_oneof![Just(64usize), Just(1_000), Just(10_000)].prop_map(Hostile::DeepHeader),
        1 => (0..ARRAY_KEYS.len(), prop_oneof![Just(5_000usize), Just(20_000)]).prop_map(|(k, n)| Hostile::HugeArray(k, n)),
        1 => prop_oneof![Just(40usize), Just(120)].prop_map(Hostile::HugeMatrix),
        1 => prop_oneof![Just(4097usize), Just(20_000)].prop_map(Hostile::HugeDiagonal),
        1 => prop_oneof![Just(10_000usize), Just(100_000)].prop_map(Hostile::LongString),
        1 => prop_oneof![Just(1_000usize), Just(5_000)].prop_map(Hostile::ManyKeys),
        2 => (0u16..1000, "[ -~\\n]{1,20}").prop_map(|(p, g)| Hostile::Garbage(p, g)),
    ]
}

/// The TOML text of a table (keys in order, sections as `[headers]`).
pub fn to_text(t: &Table) -> String {
    toml::to_string(t).unwrap_or_default()
}

fn cut(text: &str, per_mille: u16) -> usize {
    let mut at = text.len() * per_mille as usize / 1000;
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    at
}

/// The bytes of a hostile file built around the valid scenario `b`.
pub fn hostile_bytes(b: &Base, h: &Hostile) -> Vec<u8> {
    let valid = to_text(&scenario_table(b));
    let text = match h {
        Hostile::Bytes(bytes) => return bytes.clone(),
        Hostile::Truncated(p) => valid[..cut(&valid, *p)].to_string(),
        Hostile::DeepArrays(d) => format!(
            "name = \"x\"\n[plant]\na = {}1{}\n",
            "[".repeat(*d),
            "]".repeat(*d)
        ),
        Hostile::DeepInline(d) => format!(
            "name = \"x\"\n[plant]\na = {}1{}\n",
            "{ x = ".repeat(*d),
            " }".repeat(*d)
        ),
        Hostile::DeepHeader(d) => format!("name = \"x\"\n[{}]\nx = 1\n", vec!["mhe"; *d].join(".")),
        Hostile::HugeArray(k, n) => {
            let mut t = scenario_table(b);
            set(
                &mut t,
                ARRAY_KEYS[*k],
                Value::Array(vec![Value::Float(0.0); *n]),
            );
            to_text(&t)
        }
        Hostile::HugeMatrix(n) => {
            let mut t = scenario_table(b);
            set(&mut t, "plant.a", rows(&vec![0.0; n * n], *n, *n));
            to_text(&t)
        }
        Hostile::HugeDiagonal(n) => {
            let mut t = scenario_table(b);
            set(
                &mut t,
                "mhe.q",
                table(vec![(
                    "diagonal",
                    Value::Array(vec![Value::Float(1.0); *n]),
                )]),
            );
            to_text(&t)
        }
        Hostile::LongString(n) => valid.replacen("generated", &"x".repeat(*n), 1),
        Hostile::ManyKeys(n) => {
            let mut s = valid.clone();
            s.push_str("\n[zzmany]\n");
            for i in 0..*n {
                s.push_str(&format!("k{i} = {i}\n"));
            }
            s
        }
        Hostile::Garbage(p, g) => {
            let at = cut(&valid, *p);
            format!("{}{g}{}", &valid[..at], &valid[at..])
        }
    };
    text.into_bytes()
}

/// What a generated scenario file is.
#[derive(Debug, Clone)]
pub enum ScenarioCase {
    Valid(Base),
    AlmostValid(Base, Edit),
    Hostile(Base, Hostile),
}

impl ScenarioCase {
    pub fn bytes(&self) -> Vec<u8> {
        match self {
            ScenarioCase::Valid(b) => to_text(&scenario_table(b)).into_bytes(),
            ScenarioCase::AlmostValid(b, e) => to_text(&apply(b, e)).into_bytes(),
            ScenarioCase::Hostile(b, h) => hostile_bytes(b, h),
        }
    }
}

/// Valid, almost valid and hostile scenario files in the ratio 2 : 6 : 2.
pub fn scenario_case() -> impl Strategy<Value = ScenarioCase> {
    prop_oneof![
        2 => base().prop_map(ScenarioCase::Valid),
        6 => (base(), edit()).prop_map(|(b, e)| ScenarioCase::AlmostValid(b, e)),
        2 => (base(), hostile()).prop_map(|(b, h)| ScenarioCase::Hostile(b, h)),
    ]
}

// ---------------------------------------------------------------------------------------
// Sweep configs
// ---------------------------------------------------------------------------------------

/// Every key of the sweep config format (docs/sweeps.md).
pub const SWEEP_KEYS: &[&str] = &[
    "name",
    "scenario",
    "k",
    "k.from",
    "k.to",
    "k.points",
    "solvers",
    "seeds",
    "scales",
    "steps",
    "base_seed",
    "exact_mhe_solve",
    "controller",
    "controller.kind",
    "controller.iterations",
    "controller.solver",
    "metrics",
    "common_random_numbers",
    "bounded_factor",
    "certificate",
];

/// A valid tiny sweep config over `scenario` (a file name next to the config).
#[derive(Debug, Clone)]
pub struct SweepBase {
    pub k: Vec<i64>,
    pub k_range: bool,
    pub solvers: Vec<u8>,
    pub seeds: i64,
    pub scales: Option<Vec<f64>>,
    pub steps: Option<i64>,
    pub controller: u8,
    pub exact: bool,
    pub crn: bool,
}

pub fn sweep_base() -> impl Strategy<Value = SweepBase> {
    (
        vec(1i64..=4, 1..=2),
        any::<bool>(),
        vec(0u8..4, 1..=2),
        1i64..=2,
        prop::option::of(vec(0.0f64..2.0, 1..=2)),
        prop::option::of(1i64..=3),
        0u8..3,
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(
            |(k, k_range, solvers, seeds, scales, steps, controller, exact, crn)| SweepBase {
                k,
                k_range,
                solvers,
                seeds,
                scales: scales.map(|s| s.into_iter().map(round).collect()),
                steps,
                controller,
                exact,
                crn,
            },
        )
}

/// The config table of `s` over the scenario file `scenario`.
pub fn sweep_table(s: &SweepBase, scenario: &str) -> Table {
    let mut t = Table::new();
    t.insert("name".into(), Value::String("gen".into()));
    t.insert("scenario".into(), Value::String(scenario.into()));
    let k = if s.k_range {
        table(vec![
            ("from", Value::Integer(1)),
            ("to", Value::Integer(s.k.iter().copied().max().unwrap_or(1))),
            ("points", Value::Integer(2)),
        ])
    } else {
        Value::Array(s.k.iter().map(|k| Value::Integer(*k)).collect())
    };
    t.insert("k".into(), k);
    let names = ["pg", "fista", "admm", "admm-pr"];
    let mut solvers: Vec<&str> = s.solvers.iter().map(|i| names[*i as usize % 4]).collect();
    solvers.dedup();
    t.insert(
        "solvers".into(),
        Value::Array(solvers.iter().map(|n| Value::String((*n).into())).collect()),
    );
    t.insert("seeds".into(), Value::Integer(s.seeds));
    if let Some(sc) = &s.scales {
        t.insert("scales".into(), floats(sc));
    }
    if let Some(st) = s.steps {
        t.insert("steps".into(), Value::Integer(st));
    }
    let controller = match s.controller {
        0 => Value::String("exact-mpc".into()),
        1 => Value::String("saturated-lqr".into()),
        _ => table(vec![
            ("kind", Value::String("suboptimal-mpc".into())),
            ("iterations", Value::Integer(3)),
            ("solver", Value::String("fista".into())),
        ]),
    };
    t.insert("controller".into(), controller);
    t.insert("exact_mhe_solve".into(), Value::Boolean(s.exact));
    t.insert("common_random_numbers".into(), Value::Boolean(s.crn));
    // The theoretical columns take seconds per config: off, except where a test asks.
    t.insert("certificate".into(), Value::Boolean(false));
    t
}

/// One perturbation of a valid sweep config.
#[derive(Debug, Clone)]
pub enum SweepEdit {
    Replace(usize, Bad),
    Remove(usize),
    Unknown(String),
    /// `k` as a bad list / range: 0 [], 1 [0], 2 [-1], 3 beyond MAX_K, 4 range to < from,
    /// 5 points 0, 6 huge points.
    BadK(u8),
    /// A solver name that does not exist.
    Solver(String),
    /// `seeds` (or `steps`) out of range.
    Seeds(i64),
    Steps(i64),
    /// `scales` with a bad entry.
    Scale(f64),
    /// The scenario path: 0 missing file, 1 a directory, 2 an invalid scenario, 3 absolute
    /// nonsense, 4 a scenario without [mhe].
    ScenarioPath(u8),
    /// `metrics` with an unknown name or `sup_eps` without the exact solve.
    Metrics(u8),
    BoundedFactor(f64),
    /// `controller` table with a bad entry.
    Controller(u8),
}

pub fn sweep_edit() -> impl Strategy<Value = SweepEdit> {
    prop_oneof![
        4 => (0..SWEEP_KEYS.len(), bad()).prop_map(|(k, b)| SweepEdit::Replace(k, b)),
        2 => (0..SWEEP_KEYS.len()).prop_map(SweepEdit::Remove),
        1 => "zz[a-z]{1,6}".prop_map(SweepEdit::Unknown),
        2 => (0u8..7).prop_map(SweepEdit::BadK),
        1 => "[a-z\\-]{0,6}".prop_map(SweepEdit::Solver),
        1 => prop_oneof![Just(0i64), Just(-1), Just(10_000_001), Just(i64::MAX)].prop_map(SweepEdit::Seeds),
        1 => prop_oneof![Just(0i64), Just(-3), Just(100_001), Just(i64::MIN)].prop_map(SweepEdit::Steps),
        1 => bad_float().prop_map(SweepEdit::Scale),
        2 => (0u8..5).prop_map(SweepEdit::ScenarioPath),
        1 => (0u8..2).prop_map(SweepEdit::Metrics),
        1 => bad_float().prop_map(SweepEdit::BoundedFactor),
        1 => (0u8..4).prop_map(SweepEdit::Controller),
    ]
}

/// Applies `edit` to the config of `s`; scenario file names: `ok.toml` (valid),
/// `bad.toml` (invalid), `nomhe.toml` (no [mhe]), `missing.toml` (absent), `dir` (a
/// directory).
pub fn sweep_apply(s: &SweepBase, edit: &SweepEdit) -> Table {
    let mut t = sweep_table(s, "ok.toml");
    match edit {
        SweepEdit::Replace(k, bad) => {
            let key = SWEEP_KEYS[*k];
            let old = current(&mut t, key);
            set(&mut t, key, apply_bad(old, bad));
        }
        SweepEdit::Remove(k) => remove(&mut t, SWEEP_KEYS[*k]),
        SweepEdit::Unknown(n) => set(&mut t, n, Value::Integer(1)),
        SweepEdit::BadK(kind) => {
            let ints = |v: &[i64]| Value::Array(v.iter().map(|k| Value::Integer(*k)).collect());
            let range = |f: i64, to: i64, p: i64| {
                table(vec![
                    ("from", Value::Integer(f)),
                    ("to", Value::Integer(to)),
                    ("points", Value::Integer(p)),
                ])
            };
            let v = match kind {
                0 => ints(&[]),
                1 => ints(&[0]),
                2 => ints(&[3, -1]),
                3 => ints(&[10_000_001]),
                4 => range(10, 2, 3),
                5 => range(1, 10, 0),
                _ => range(1, 10, i64::MAX),
            };
            set(&mut t, "k", v);
        }
        SweepEdit::Solver(n) => {
            set(
                &mut t,
                "solvers",
                Value::Array(vec![Value::String(n.clone())]),
            );
        }
        SweepEdit::Seeds(v) => set(&mut t, "seeds", Value::Integer(*v)),
        SweepEdit::Steps(v) => set(&mut t, "steps", Value::Integer(*v)),
        SweepEdit::Scale(v) => set(&mut t, "scales", floats(&[1.0, *v])),
        SweepEdit::ScenarioPath(kind) => {
            let p = match kind {
                0 => "missing.toml",
                1 => "dir",
                2 => "bad.toml",
                3 => "/nonexistent/\u{0}x.toml",
                _ => "nomhe.toml",
            };
            set(&mut t, "scenario", Value::String(p.into()));
        }
        SweepEdit::Metrics(kind) => {
            let m = if *kind == 0 { "sup_zz" } else { "sup_eps" };
            set(&mut t, "exact_mhe_solve", Value::Boolean(false));
            set(
                &mut t,
                "metrics",
                Value::Array(vec![Value::String(m.into())]),
            );
        }
        SweepEdit::BoundedFactor(v) => set(&mut t, "bounded_factor", Value::Float(*v)),
        SweepEdit::Controller(kind) => {
            let v = match kind {
                0 => Value::String("lqr".into()),
                1 => table(vec![
                    ("kind", Value::String("suboptimal-mpc".into())),
                    ("iterations", Value::Integer(0)),
                ]),
                2 => table(vec![
                    ("kind", Value::String("suboptimal-mpc".into())),
                    ("iterations", Value::Integer(3)),
                    ("solver", Value::String("newton".into())),
                ]),
                _ => table(vec![
                    ("kind", Value::String("exact-mpc".into())),
                    ("zz", Value::Integer(1)),
                ]),
            };
            set(&mut t, "controller", v);
        }
    }
    t
}

/// What a generated sweep config is.
#[derive(Debug, Clone)]
pub enum SweepCase {
    Valid(SweepBase),
    AlmostValid(SweepBase, SweepEdit),
    Hostile(Base, Hostile),
}

impl SweepCase {
    pub fn bytes(&self) -> Vec<u8> {
        match self {
            SweepCase::Valid(s) => to_text(&sweep_table(s, "ok.toml")).into_bytes(),
            SweepCase::AlmostValid(s, e) => to_text(&sweep_apply(s, e)).into_bytes(),
            SweepCase::Hostile(b, h) => hostile_bytes(b, h),
        }
    }
}

pub fn sweep_case() -> impl Strategy<Value = SweepCase> {
    prop_oneof![
        2 => sweep_base().prop_map(SweepCase::Valid),
        6 => (sweep_base(), sweep_edit()).prop_map(|(s, e)| SweepCase::AlmostValid(s, e)),
        2 => (base(), hostile()).prop_map(|(b, h)| SweepCase::Hostile(b, h)),
    ]
}

/// The files a sweep config may point at, written into `dir`: `ok.toml` (valid, tiny),
/// `bad.toml` (invalid), `nomhe.toml` (no [mhe]) and the directory `dir`.
pub fn write_sweep_scenarios(dir: &std::path::Path) -> std::io::Result<()> {
    let ok = r#"
name = "ok"
[plant]
a = [[0.9, 0.1], [0.0, 0.8]]
b = [[0.0], [1.0]]
c = [[1.0, 0.0]]
[sets]
input = { lower = [-1.0], upper = [1.0] }
disturbance = { lower = -0.1, upper = 0.1 }
[simulation]
x0 = [1.0, -1.0]
steps = 3
[mhe]
horizon = 2
eta = 0.8
iterations = 3
[mpc]
horizon = 2
"#;
    std::fs::write(dir.join("ok.toml"), ok)?;
    std::fs::write(dir.join("bad.toml"), ok.replace("eta = 0.8", "eta = 1.5"))?;
    let nomhe: String = ok.split("[mhe]").next().unwrap_or(ok).to_string();
    std::fs::write(dir.join("nomhe.toml"), nomhe)?;
    std::fs::create_dir_all(dir.join("dir"))?;
    Ok(())
}

// ---------------------------------------------------------------------------------------
// The property: a failure names a user key or the file
// ---------------------------------------------------------------------------------------

/// The names between backticks in `msg`.
pub fn backticked(msg: &str) -> Vec<&str> {
    msg.split('`').skip(1).step_by(2).collect()
}

/// Whether `token` is a user key: a scenario or sweep key (with an element index or a
/// sub-key), an unknown key the generator made up (`zz…`), or `<toml>` / `<file>` / `<root>`.
pub fn is_user_key(token: &str) -> bool {
    let base = token.split('[').next().unwrap_or(token);
    if ["<toml>", "<file>", "<root>"].contains(&base) || base.starts_with("zz") {
        return true;
    }
    let known = |k: &&str| base == *k || base.starts_with(&format!("{k}."));
    SCENARIO_KEYS.iter().any(known)
        || SWEEP_KEYS.iter().any(known)
        || base
            .split('.')
            .next_back()
            .is_some_and(|l| l.starts_with("zz"))
}

/// Whether the message names a user key (between backticks) or one of `paths`.
pub fn names_user_key(msg: &str, paths: &[&str]) -> bool {
    backticked(msg).into_iter().any(is_user_key)
        || paths.iter().any(|p| !p.is_empty() && msg.contains(p))
}

/// `e` and its sources, joined by ": " (what anyhow's `{:#}` prints).
pub fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut out = e.to_string();
    let mut cur = e.source();
    while let Some(s) = cur {
        let text = s.to_string();
        if !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
        cur = s.source();
    }
    out
}
