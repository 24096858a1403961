pub mod fdr;
pub mod malt;
