//! The MPC's stored measurements: the loop program's control part and whole step.

use crate::{MPC_POINTS_CSV, Point, Scalar, StepDims, Target, data_lines};

/// One measured loop step of `data/cortex-m-mpc-points.csv`: the loop program (MHE + the
/// K_c-iteration MPC), its control part counted on its own.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LoopPoint {
    /// The control part: the MPC's method, sizes ([`StepDims::mpc`]), K_c and max
    /// instructions (what its rows are fitted on).
    pub mpc: Point,
    /// The loop's MHE method.
    pub mhe_method: String,
    /// The loop's MHE window.
    pub mhe_dims: StepDims,
    /// The loop's MHE K.
    pub mhe_k: usize,
    /// Max instructions of the whole loop step (push + estimate + control).
    pub loop_max: f64,
}

/// Every stored loop measurement.
pub fn loop_points() -> Result<Vec<LoopPoint>, String> {
    let mut out = Vec::new();
    for (line_no, line) in data_lines(MPC_POINTS_CSV).skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let bad = || format!("data/cortex-m-mpc-points.csv line {line_no}: `{line}` is malformed");
        if f.len() != 20 {
            return Err(bad());
        }
        let int = |i: usize| f[i].trim().parse::<usize>().map_err(|_| bad());
        let num = |i: usize| f[i].trim().parse::<f64>().map_err(|_| bad());
        let (nx, nu) = (int(6)?, int(7)?);
        out.push(LoopPoint {
            mpc: Point {
                target: Target::parse(f[0]).map_err(|_| bad())?,
                method: f[1].to_string(),
                scalar: Scalar::parse(f[12]).ok_or_else(bad)?,
                scenario: f[2].to_string(),
                dims: StepDims::mpc(nx, nu, int(3)?),
                k: int(9)?,
                max: num(11)?,
            },
            mhe_method: f[13].to_string(),
            mhe_dims: StepDims {
                horizon: int(14)?,
                n: int(15)?,
                n_theta: int(16)?,
                nx,
                nu,
            },
            mhe_k: int(17)?,
            loop_max: num(19)?,
        });
    }
    Ok(out)
}
