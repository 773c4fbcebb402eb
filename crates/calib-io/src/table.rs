//! Correction tables.
