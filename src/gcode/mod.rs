//! G-code programs.
