pub mod malt;
