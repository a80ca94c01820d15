//! Test plants from the literature for the certificate beyond the case study (issue 11).
//! Also included by `examples/gamma13_plants.rs` (`#[path]`), so the figures it prints are
//! those of the tests.
#![allow(dead_code, clippy::unwrap_used)]

use faer::{Mat, mat};
use lti_model::{BoxSet, LtiSystem};
use mpc_core::{CondensedMpc, MpcConfig};

/// Inverted pendulum on a cart, linearised about the upright position: "Inverted Pendulum:
/// System Modeling", Control Tutorials for MATLAB and Simulink (University of Michigan,
/// ctms.engin.umich.edu), with M = 0.5 kg (cart), m = 0.2 kg, b = 0.1 N·s/m, l = 0.3 m,
/// I = 0.006 kg·m², g = 9.8 m/s²; state (x, ẋ, φ, φ̇), input the force F, outputs x and φ:
///
/// ẋ = [[0, 1, 0, 0], [0, −(I+ml²)b/p, m²gl²/p, 0], [0, 0, 0, 1], [0, −mlb/p, mgl(M+m)/p, 0]]x
///   + [0, (I+ml²)/p, 0, ml/p]ᵀF,  p = I(M+m) + Mml².
///
/// Discretised by zero-order hold with sampling time `ts`. Its unstable pole is s = 5.565,
/// so at ts = 0.02 s the discrete eigenvalue is e^{5.565·0.02} = 1.118.
pub fn cart_pendulum(ts: f64) -> LtiSystem {
    let (mc, m, b, l, i, g) = (0.5, 0.2, 0.1, 0.3, 0.006, 9.8);
    let p = i * (mc + m) + mc * m * l * l;
    let a_c = mat![
        [0.0, 1.0, 0.0, 0.0],
        [0.0, -(i + m * l * l) * b / p, m * m * g * l * l / p, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [0.0, -m * l * b / p, m * g * l * (mc + m) / p, 0.0],
    ];
    let b_c = mat![[0.0], [(i + m * l * l) / p], [0.0], [m * l / p]];
    let (a, bd) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), ts).unwrap();
    LtiSystem::new(a, bd, mat![[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]).unwrap()
}

/// MPC of the pendulum: N = 10, Q_c = I₄, R_c = 0.1, DARE terminal cost, input set `input`.
pub fn cart_pendulum_mpc(ts: f64, input: BoxSet) -> CondensedMpc {
    CondensedMpc::new(
        &cart_pendulum(ts),
        MpcConfig::new(10, Mat::identity(4, 4), mat![[0.1]], input),
    )
    .unwrap()
}

/// Chain of six unit masses joined to each other and to walls at both ends by unit springs
/// and dampers (coefficient `damping`), three actuators exerting tensions between masses
/// (1, 2), (3, 4) and (5, 6): the oscillating-masses benchmark of Wang & Boyd, "Fast model
/// predictive control using online optimization", IEEE TCST 18(2), 2010 (there without
/// damping), ZOH at T_s = 0.5. State (positions, velocities), n_x = 12, n_u = 3; outputs the
/// positions.
pub fn mass_chain(damping: f64) -> LtiSystem {
    let n = 6;
    let mut lap = Mat::<f64>::zeros(n, n); // stiffness matrix of the chain with both walls
    for i in 0..n {
        lap[(i, i)] = 2.0;
        if i + 1 < n {
            lap[(i, i + 1)] = -1.0;
            lap[(i + 1, i)] = -1.0;
        }
    }
    let a_c = Mat::from_fn(2 * n, 2 * n, |r, c| match (r < n, c < n) {
        (true, true) => 0.0,
        (true, false) => f64::from(u8::from(c - n == r)),
        (false, true) => -lap[(r - n, c)],
        (false, false) => -damping * lap[(r - n, c - n)],
    });
    let mut b_c = Mat::<f64>::zeros(2 * n, 3);
    for k in 0..3 {
        b_c[(n + 2 * k, k)] = 1.0;
        b_c[(n + 2 * k + 1, k)] = -1.0;
    }
    let (a, b) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), 0.5).unwrap();
    let c = Mat::from_fn(n, 2 * n, |r, col| f64::from(u8::from(r == col)));
    LtiSystem::new(a, b, c).unwrap()
}

/// MPC of the chain: horizon `n`, Q_c = I₁₂, R_c = I₃, DARE terminal cost, |u_i| ≤ 0.5.
pub fn mass_chain_mpc(damping: f64, n: usize) -> CondensedMpc {
    CondensedMpc::new(
        &mass_chain(damping),
        MpcConfig::new(
            n,
            Mat::identity(12, 12),
            Mat::identity(3, 3),
            BoxSet::symmetric(&[0.5, 0.5, 0.5]).unwrap(),
        ),
    )
    .unwrap()
}

fn toml_matrix(m: faer::MatRef<'_, f64>) -> String {
    let rows: Vec<String> = (0..m.nrows())
        .map(|i| {
            let r: Vec<String> = (0..m.ncols()).map(|j| format!("{:?}", m[(i, j)])).collect();
            format!("[{}]", r.join(", "))
        })
        .collect();
    format!("[{}]", rows.join(", "))
}

fn toml_vector(v: &[f64]) -> String {
    let r: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", r.join(", "))
}

/// A scenario (TOML text, parsed) for `sys` with the MPC of horizon `n`, Q_c = I, R_c =
/// `r_c`·I, the input box ±`input` (`None`: `sets.input` omitted, 𝒰 = ℝ^{n_u}), noise
/// uniform in ±0.01, and the MHE of the certified preset (M = 9, η = 0.8, Q = I, R = I, PG).
pub fn scenario(
    name: &str,
    sys: &LtiSystem,
    input: Option<f64>,
    n: usize,
    r_c: f64,
    x0: &[f64],
) -> closed_loop::scenario::Scenario {
    let (nx, nu, ny) = (sys.nx(), sys.nu(), sys.ny());
    let input = input.map_or(String::new(), |u| {
        format!(
            "input = {{ lower = {}, upper = {} }}\n",
            toml_vector(&vec![-u; nu]),
            toml_vector(&vec![u; nu])
        )
    });
    let text = format!(
        "name = \"{name}\"\n\
         [plant]\na = {}\nb = {}\nc = {}\n\
         [sets]\n{input}disturbance = {{ lower = {}, upper = {} }}\n\
         [noise]\nkind = \"uniform\"\nscale = 1.0\nseed = 11\n\
         [simulation]\nx0 = {}\nprior = {}\nsteps = 40\n\
         [mhe]\nhorizon = 9\neta = 0.8\nq = 1.0\nr = 1.0\niterations = 10\nsolver = \"pg\"\nwarm_start = \"paper\"\n\
         [mpc]\nhorizon = {n}\nq = 1.0\nr = {r_c:?}\nterminal = \"dare\"\n",
        toml_matrix(sys.a()),
        toml_matrix(sys.b()),
        toml_matrix(sys.c()),
        toml_vector(&vec![-0.01; nx + ny]),
        toml_vector(&vec![0.01; nx + ny]),
        toml_vector(x0),
        toml_vector(&vec![0.0; nx]),
    );
    closed_loop::scenario::Scenario::from_toml_str(&text).unwrap()
}

#[test]
#[ignore = "prints the cart-pendulum scenario text (used to write scenarios/cart-pendulum.toml)"]
fn print_cart_pendulum_scenario() {
    let s = scenario(
        "cart-pendulum",
        &cart_pendulum(0.02),
        None,
        10,
        0.1,
        &[0.0, 0.0, 0.1, 0.0],
    );
    println!("{}", s.source.unwrap());
}
