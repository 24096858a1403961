pub mod cg_bench;
pub mod coarse_grain;
pub mod fdr;
pub mod impact;
pub mod malt;
pub mod stress;
pub mod stress_fields;
