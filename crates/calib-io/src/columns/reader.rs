//! Turns a [`super::ColumnSet`] into samples (written next).
