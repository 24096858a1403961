pub mod fdr;
pub mod malt;
pub mod coarse_grain;
pub mod stress;
pub mod cg_bench;
