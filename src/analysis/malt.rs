//! TEMPORARY stub while the MALT module is being written; replaced by the real module.
pub struct Quad { pub value: f64, pub abs_err: f64 }
pub fn k_phi(_phi: f64) -> anyhow::Result<Quad> { anyhow::bail!("MALT not yet available") }
pub fn phi_of_k(_k: f64) -> anyhow::Result<f64> { anyhow::bail!("MALT not yet available") }
pub fn table(_m: f64, _s: f64) -> anyhow::Result<Vec<(f64, f64)>> { anyhow::bail!("MALT not yet available") }
