//! Groove cross-section profiles.
pub mod standard;
