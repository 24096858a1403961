pub mod fdr;
pub mod malt;
pub mod impact;
