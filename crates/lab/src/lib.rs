//! The lab: measurements behind `neural-cloth bench` ([`bench`], including the per-term cost of
//! the physics) and `neural-cloth report` ([`report`]: what accuracy costs in time, effects and
//! settings, the paper's claims on small scenes). It sits above training and below the app,
//! whose "Cost" panel runs [`report::accuracy`].

pub mod bench;
pub mod report;
