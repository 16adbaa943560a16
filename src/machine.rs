//! Machine profiles.
