//! Placeholder replaced below.
pub fn run(_n: usize, _steps: u64) -> anyhow::Result<()> { anyhow::bail!("bench not built yet") }
