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
/// (1, 2), (3, 4) and (5, 6); ZOH at T_s = 0.5. State (positions, velocities), n_x = 12,
/// n_u = 3; outputs the positions. Modelled on the oscillating-masses benchmark of Wang &
/// Boyd, "Fast model predictive control using online optimization", IEEE TCST 18(2), 2010
/// (there without damping, and with the actuators between masses (1, 2), (3, 5) and (4, 6):
/// see [`wang_boyd_chain`], which follows the authors' code).
pub fn mass_chain(damping: f64) -> LtiSystem {
    chain(damping, [(0, 1), (2, 3), (4, 5)])
}

/// The oscillating masses of Wang & Boyd, "Fast model predictive control using online
/// optimization", IEEE Trans. Control Syst. Technol. 18(2):267–278, 2010, Sec. V-A, as
/// set up in the authors' script `masses_example.m` (fast_mpc, web.stanford.edu/~boyd/fast_mpc;
/// the same lines are in qpDUNES' `examples/matlab/Wang2010/setupOscillator.m`): six unit
/// masses, unit springs between neighbours and to the walls at both ends, damping constant
/// `damping` (λ = 0 in the source), three actuators exerting tensions between masses (1, 2),
/// (3, 5) and (4, 6), ZOH at T_s = 0.5. State (positions p, velocities v), n_x = 12, n_u = 3:
///
/// ẋ = [[0, I], [−L, −λL]]x + [0; B_v]u,  L = tridiag(−1, 2, −1) (6×6),
/// B_v columns e₁ − e₂, e₃ − e₅, e₄ − e₆.
///
/// Outputs: the positions (C = [I₆ 0]; the source assumes full state information).
pub fn wang_boyd_chain(damping: f64) -> LtiSystem {
    chain(damping, [(0, 1), (2, 4), (3, 5)])
}

/// Six-mass chain with tensions between the mass pairs `actuators` (0-based), ZOH at 0.5.
fn chain(damping: f64, actuators: [(usize, usize); 3]) -> LtiSystem {
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
    for (k, (i, j)) in actuators.into_iter().enumerate() {
        b_c[(n + i, k)] = 1.0;
        b_c[(n + j, k)] = -1.0;
    }
    let (a, b) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), 0.5).unwrap();
    let c = Mat::from_fn(n, 2 * n, |r, col| f64::from(u8::from(r == col)));
    LtiSystem::new(a, b, c).unwrap()
}

/// [`wang_boyd_chain`] with the disturbance model of the authors' simulation: w¹ ∈ ℝ⁶ adds
/// to the six velocities only (x⁺ = Ax + Bu + [0; I₆]w¹, rank E = 6 < n_x = 12).
pub fn wang_boyd_chain_velocity_noise(damping: f64) -> LtiSystem {
    let s = wang_boyd_chain(damping);
    let e = Mat::from_fn(12, 6, |r, c| f64::from(u8::from(r == c + 6)));
    LtiSystem::with_disturbance(
        s.a().to_owned(),
        s.b().to_owned(),
        s.c().to_owned(),
        e,
        Mat::identity(6, 6),
    )
    .unwrap()
}

/// The double integrator ÿ = u (a unit mass driven by a force), ZOH with sampling time
/// `ts`: A = [[1, T], [0, 1]], B = [T²/2, T]ᵀ; output the position. Both eigenvalues are 1
/// (a Jordan block): marginally stable, and unstable under any constant input.
pub fn double_integrator(ts: f64) -> LtiSystem {
    let a_c = mat![[0.0, 1.0], [0.0, 0.0]];
    let b_c = mat![[0.0], [1.0]];
    let (a, b) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), ts).unwrap();
    LtiSystem::new(a, b, mat![[1.0, 0.0]]).unwrap()
}

/// The quadruple-tank process of K. H. Johansson, "The quadruple-tank process: a
/// multivariable laboratory process with an adjustable zero", IEEE Trans. Control Syst.
/// Technol. 8(3):456–465, 2000, linearised at the minimum-phase operating point P₋.
/// Parameters (Tables I and II): A₁ = A₃ = 28 cm², A₂ = A₄ = 32 cm² (tank sections),
/// a₁ = a₃ = 0.071 cm², a₂ = a₄ = 0.057 cm² (outlet holes), k_c = 0.5 V/cm, g = 981 cm/s²;
/// at P₋: h⁰ = (12.4, 12.7, 1.8, 1.4) cm, v⁰ = (3.00, 3.00) V, (k₁, k₂) = (3.33, 3.35)
/// cm³/(V·s), (γ₁, γ₂) = (0.70, 0.60). With T_i = (A_i/a_i)√(2h⁰_i/g) (62.7, 90.3, 23.9 and
/// 30.0 s):
///
/// ```text
/// ẋ = [[−1/T₁, 0, A₃/(A₁T₃), 0], [0, −1/T₂, 0, A₄/(A₂T₄)], [0, 0, −1/T₃, 0], [0, 0, 0, −1/T₄]]x
///   + [[γ₁k₁/A₁, 0], [0, γ₂k₂/A₂], [0, (1−γ₂)k₂/A₃], [(1−γ₁)k₁/A₄, 0]]u,
/// y = [[k_c, 0, 0, 0], [0, k_c, 0, 0]]x,
/// ```
///
/// x the level deviations (cm), u the pump-voltage deviations (V), y the level sensor
/// voltages of the two lower tanks; ZOH with sampling time `ts` (s).
pub fn quadruple_tank(ts: f64) -> LtiSystem {
    let (area, hole): ([f64; 4], [f64; 4]) =
        ([28.0, 32.0, 28.0, 32.0], [0.071, 0.057, 0.071, 0.057]);
    let (kc, g, h0): (f64, f64, [f64; 4]) = (0.5, 981.0, [12.4, 12.7, 1.8, 1.4]);
    let (k, gamma) = ([3.33, 3.35], [0.70, 0.60]);
    let t: Vec<f64> = (0..4)
        .map(|i| area[i] / hole[i] * (2.0 * h0[i] / g).sqrt())
        .collect();
    let a_c = mat![
        [-1.0 / t[0], 0.0, area[2] / (area[0] * t[2]), 0.0],
        [0.0, -1.0 / t[1], 0.0, area[3] / (area[1] * t[3])],
        [0.0, 0.0, -1.0 / t[2], 0.0],
        [0.0, 0.0, 0.0, -1.0 / t[3]],
    ];
    let b_c = mat![
        [gamma[0] * k[0] / area[0], 0.0],
        [0.0, gamma[1] * k[1] / area[1]],
        [0.0, (1.0 - gamma[1]) * k[1] / area[2]],
        [(1.0 - gamma[0]) * k[0] / area[3], 0.0],
    ];
    let (a, b) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), ts).unwrap();
    LtiSystem::new(a, b, mat![[kc, 0.0, 0.0, 0.0], [0.0, kc, 0.0, 0.0]]).unwrap()
}

/// A 20-node thermal rod: the heat equation ∂T/∂t = α ∂²T/∂ξ² − β(T − T_amb) on an
/// aluminium rod of length 0.4 m with insulated ends, discretised in space by finite
/// differences on 20 nodes (h = 0.02 m, the Neumann ends by mirrored ghost nodes), with two
/// heaters at nodes 6 and 15 and thermocouples at nodes 1, 10 and 20 (1-based):
///
/// ```text
/// ẋ = (α/h²)·L·x − β·x + B_c u,   L = tridiag(1, −2, 1) with L₁₁ = L₂₀,₂₀ = −1,
/// B_c = e₆, e₁₅ columns × 1/(ρc_p·A·h),   y = (x₁, x₁₀, x₂₀),
/// ```
///
/// α = 9.7·10⁻⁵ m²/s (aluminium: α/h² = 0.2425 s⁻¹), β = 0.01 s⁻¹ (convective loss to the
/// ambient, a 100 s time constant), ρc_p = 2.42·10⁶ J/(m³K), cross-section A = 10⁻⁴ m²
/// (so one watt heats a node by 1/4.84 K/s); x the temperature deviations from the ambient
/// (K), u the heater powers (W). ZOH with sampling time `ts` (s).
pub fn thermal_rod(ts: f64) -> LtiSystem {
    let n = 20;
    let (alpha, h, beta) = (9.7e-5_f64, 0.02_f64, 0.01_f64);
    let k = alpha / (h * h);
    let a_c = Mat::from_fn(n, n, |i, j| {
        if i == j {
            let neighbours = if i == 0 || i == n - 1 { 1.0 } else { 2.0 };
            -k * neighbours - beta
        } else if i.abs_diff(j) == 1 {
            k
        } else {
            0.0
        }
    });
    let gain = 1.0 / (2.42e6 * 1e-4 * h);
    let b_c = Mat::from_fn(n, 2, |i, j| {
        if (j == 0 && i == 5) || (j == 1 && i == 14) {
            gain
        } else {
            0.0
        }
    });
    let c = Mat::from_fn(3, n, |r, j| f64::from(u8::from([0, 9, 19][r] == j)));
    let (a, b) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), ts).unwrap();
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

/// What [`scenario_text`] writes besides the plant: the MHE is that of the certified
/// preset (M = 9, η = 0.8, Q = I, R = I, paper warm start), the MPC has Q_c = I and a DARE
/// terminal cost, the noise is uniform on `noise_scale`·𝒲, the prior is 0.
pub struct Spec<'a> {
    /// `name`.
    pub name: &'a str,
    /// The plant (E is written only when it is not I; F is I).
    pub sys: &'a LtiSystem,
    /// Symmetric input box ±`input` (`None`: `sets.input` omitted, 𝒰 = ℝ^{n_u}).
    pub input: Option<f64>,
    /// Half-widths of 𝒲: w¹ components, then w² components.
    pub w: (f64, f64),
    /// `noise.scale`.
    pub noise_scale: f64,
    /// `simulation.x0`.
    pub x0: &'a [f64],
    /// `simulation.steps`.
    pub steps: usize,
    /// `mhe.iterations` and `mhe.method`.
    pub mhe: (usize, &'a str),
    /// MPC horizon N and R_c = r_c·I.
    pub mpc: (usize, f64),
}

/// The scenario file body (TOML) of `spec`.
pub fn scenario_text(spec: &Spec<'_>) -> String {
    scenario_text_with_horizon(spec, 9)
}

/// [`scenario_text`] with the MHE horizon `m` (η = 0.8 as in the certified preset).
pub fn scenario_text_with_horizon(spec: &Spec<'_>, m: usize) -> String {
    let sys = spec.sys;
    let (nx, nu, nw1, nw2) = (sys.nx(), sys.nu(), sys.nw1(), sys.nw2());
    let input = spec.input.map_or(String::new(), |u| {
        format!(
            "input = {{ lower = {}, upper = {} }}\n",
            toml_vector(&vec![-u; nu]),
            toml_vector(&vec![u; nu])
        )
    });
    let identity = nw1 == nx
        && (0..nx).all(|i| (0..nx).all(|j| sys.e()[(i, j)] == f64::from(u8::from(i == j))));
    let e = if identity {
        String::new()
    } else {
        format!("e = {}\n", toml_matrix(sys.e()))
    };
    let (lower, upper): (Vec<f64>, Vec<f64>) = (0..nw1 + nw2)
        .map(|i| if i < nw1 { spec.w.0 } else { spec.w.1 })
        .map(|h| (-h, h))
        .unzip();
    let (k, method) = spec.mhe;
    let (n, r_c) = spec.mpc;
    format!(
        "name = \"{}\"\n\
         [plant]\na = {}\nb = {}\nc = {}\n{e}\
         [sets]\n{input}disturbance = {{ lower = {}, upper = {} }}\n\
         [noise]\nkind = \"uniform\"\nscale = {:?}\nseed = 11\n\
         [simulation]\nx0 = {}\nprior = {}\nsteps = {}\n\
         [mhe]\nhorizon = {m}\neta = 0.8\nq = 1.0\nr = 1.0\niterations = {k}\nmethod = \"{method}\"\nwarm_start = \"paper\"\n\
         [mpc]\nhorizon = {n}\nq = 1.0\nr = {r_c:?}\nterminal = \"dare\"\n",
        spec.name,
        toml_matrix(sys.a()),
        toml_matrix(sys.b()),
        toml_matrix(sys.c()),
        toml_vector(&lower),
        toml_vector(&upper),
        spec.noise_scale,
        toml_vector(spec.x0),
        toml_vector(&vec![0.0; nx]),
        spec.steps,
    )
}

/// A scenario (parsed) for `sys` with the MPC of horizon `n`, Q_c = I, R_c = `r_c`·I, the
/// input box ±`input` (`None`: `sets.input` omitted, 𝒰 = ℝ^{n_u}), noise uniform in ±0.01,
/// 40 steps, and the MHE of the certified preset with PG and K = 10.
pub fn scenario(
    name: &str,
    sys: &LtiSystem,
    input: Option<f64>,
    n: usize,
    r_c: f64,
    x0: &[f64],
) -> closed_loop::scenario::Scenario {
    let text = scenario_text(&Spec {
        name,
        sys,
        input,
        w: (0.01, 0.01),
        noise_scale: 1.0,
        x0,
        steps: 40,
        mhe: (10, "pg"),
        mpc: (n, r_c),
    });
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

/// The scenario bodies of the coverage table (docs/certificate-coverage.md), by file name.
/// The files under `scenarios/` are these bodies below a hand-written derivation comment;
/// `coverage::shipped_matrices_are_the_derivations` checks that they still agree.
/// The sample period a shipped coverage scenario states (`plant.sample_time`), if any.
fn sample_time(file: &str) -> Option<f64> {
    match file {
        "mass-chain.toml" | "mass-chain-light-damping.toml" => Some(0.5),
        "cart-pendulum-bounded.toml" => Some(0.02),
        "double-integrator.toml" => Some(0.1),
        "quadruple-tank.toml" => Some(5.0),
        "thermal-rod-m10.toml" | "thermal-rod-m30.toml" => Some(2.0),
        _ => None,
    }
}

pub fn coverage_scenarios() -> Vec<(&'static str, String)> {
    let positions_displaced: Vec<f64> = (0..12).map(|i| if i < 6 { 1.0 } else { 0.0 }).collect();
    let chain = |name, sys: &LtiSystem, w1, mhe| {
        scenario_text(&Spec {
            name,
            sys,
            input: Some(0.5),
            w: (w1, 0.01),
            noise_scale: 1.0,
            x0: &positions_displaced,
            steps: 40,
            mhe,
            mpc: (30, 1.0),
        })
    };
    let bodies = vec![
        (
            "mass-chain.toml",
            chain("mass-chain", &wang_boyd_chain(1.0), 0.5, (10, "admm-pr")),
        ),
        (
            "mass-chain-light-damping.toml",
            chain(
                "mass-chain-light-damping",
                &wang_boyd_chain(0.5),
                0.5,
                (10, "admm-pr"),
            ),
        ),
        (
            "mass-chain-velocity-noise.toml",
            chain(
                "mass-chain-velocity-noise",
                &wang_boyd_chain_velocity_noise(1.0),
                0.5,
                (10, "admm-pr"),
            ),
        ),
        (
            "mass-chain-undamped.toml",
            chain(
                "mass-chain-undamped",
                &wang_boyd_chain_velocity_noise(0.0),
                0.5,
                (10, "pg"),
            ),
        ),
        (
            "cart-pendulum-bounded.toml",
            scenario_text(&Spec {
                name: "cart-pendulum-bounded",
                sys: &cart_pendulum(0.02),
                input: Some(5.0),
                w: (0.01, 0.01),
                noise_scale: 0.5,
                x0: &[0.0, 0.0, 0.1, 0.0],
                steps: 150,
                mhe: (10, "pg"),
                mpc: (10, 0.1),
            }),
        ),
        (
            "double-integrator.toml",
            scenario_text(&Spec {
                name: "double-integrator",
                sys: &double_integrator(0.1),
                input: None,
                w: (0.01, 0.01),
                noise_scale: 1.0,
                x0: &[1.0, 0.0],
                steps: 100,
                mhe: (10, "admm-pr"),
                mpc: (10, 1.0),
            }),
        ),
        (
            "quadruple-tank.toml",
            scenario_text(&Spec {
                name: "quadruple-tank",
                sys: &quadruple_tank(5.0),
                input: Some(3.0),
                w: (0.05, 0.01),
                noise_scale: 1.0,
                x0: &[2.0, 2.0, 1.0, 1.0],
                steps: 100,
                mhe: (10, "admm-pr"),
                mpc: (10, 1.0),
            }),
        ),
        (
            "thermal-rod-m10.toml",
            thermal_rod_text("thermal-rod-m10", 10, 10),
        ),
        (
            "thermal-rod-m30.toml",
            thermal_rod_text("thermal-rod-m30", 30, 8),
        ),
    ];
    // `plant.sample_time`: the zero-order-hold period the shipped file states (issue 36).
    bodies
        .into_iter()
        .map(|(file, body)| match sample_time(file) {
            Some(ts) => (
                file,
                body.replacen("[plant]\n", &format!("[plant]\nsample_time = {ts:?}\n"), 1),
            ),
            None => (file, body),
        })
        .collect()
}

/// The thermal rod's scenario (T_s = 2 s): heaters ±2 W, w¹ ±0.01 K per step at every
/// node, thermocouple noise ±0.05 K, 1 K initial deviation, MHE horizon `m`, MPC horizon `n`
/// with R_c = 0.1, ADMM α = 2 at K = 10, 60 steps.
fn thermal_rod_text(name: &str, m: usize, n: usize) -> String {
    scenario_text_with_horizon(
        &Spec {
            name,
            sys: &thermal_rod(2.0),
            input: Some(2.0),
            w: (0.01, 0.05),
            noise_scale: 1.0,
            x0: &[1.0; 20],
            steps: 60,
            mhe: (10, "admm-pr"),
            mpc: (n, 0.1),
        },
        m,
    )
}

#[test]
#[ignore = "prints the coverage scenario bodies (used to write the files under scenarios/)"]
fn print_coverage_scenarios() {
    for (file, text) in coverage_scenarios() {
        closed_loop::scenario::Scenario::from_toml_str(&text).unwrap();
        println!("==> {file}\n{text}");
    }
}
