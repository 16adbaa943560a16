//! Standard thread profiles.
