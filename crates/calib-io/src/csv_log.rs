//! CSV logs.
