pub mod fdr;
pub mod impact;
pub mod malt;
