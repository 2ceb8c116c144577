//! The baselines: [`cloth`] (the standard cloth benchmark stepped by one loop over the
//! springs) and [`paper_transfer`] (the paper's §5 transfer done literally, every frame).

pub mod cloth;
pub mod paper_transfer;
