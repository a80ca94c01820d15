//! The dense kernel of the process, chosen by the tool: qp-iter never reads the environment
//! (`qp_iter::kernel::set_global_kernel`), so `cargo xtask` reads `QP_ITER_KERNEL` here,
//! once, before any map is built.

use anyhow::{Result, bail};
use qp_iter::kernel::{self, Kernel, KernelPath};

/// The variable: `portable` (bit for bit what `mhe-embedded` and the exported C compute),
/// `avx2+fma`, or `auto` / unset (the fastest the CPU supports).
pub const KERNEL_ENV: &str = "QP_ITER_KERNEL";

/// The kernel a value of [`KERNEL_ENV`] names; an error naming the variable and the values
/// it takes otherwise (also for `avx2+fma` on a CPU without AVX2 and FMA).
pub fn parse_kernel(value: &str) -> Result<Kernel> {
    let path = match value.trim() {
        "" | "auto" => return Ok(Kernel::detect()),
        "portable" => KernelPath::Portable,
        "avx2+fma" | "avx2" => KernelPath::Avx2Fma,
        other => bail!(
            "{KERNEL_ENV} = `{other}` is not a kernel; use `portable`, `avx2+fma` or `auto` (or unset it)"
        ),
    };
    match Kernel::with_path(path) {
        Some(k) => Ok(k),
        None => bail!(
            "{KERNEL_ENV} = `{value}`: this CPU cannot run the {} kernel; use `portable` or `auto`",
            path.name()
        ),
    }
}

/// Reads [`KERNEL_ENV`] and sets the kernel every map of this process is built with.
pub fn set_from_env() -> Result<()> {
    let Some(value) = std::env::var_os(KERNEL_ENV) else {
        return Ok(());
    };
    let Some(value) = value.to_str() else {
        bail!("{KERNEL_ENV} is not UTF-8; use `portable`, `avx2+fma` or `auto`");
    };
    kernel::set_global_kernel(parse_kernel(value)?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_name_their_kernel_and_others_are_rejected() {
        assert_eq!(parse_kernel("portable").ok(), Some(Kernel::portable()));
        assert_eq!(parse_kernel("auto").ok(), Some(Kernel::detect()));
        assert_eq!(parse_kernel("").ok(), Some(Kernel::detect()));
        let avx = parse_kernel("avx2+fma");
        assert_eq!(avx.is_ok(), KernelPath::Avx2Fma.is_available());
        let e = parse_kernel("fast").expect_err("not a kernel").to_string();
        assert!(
            e.contains("QP_ITER_KERNEL") && e.contains("portable"),
            "{e}"
        );
    }
}
