//! MCAP logs.
