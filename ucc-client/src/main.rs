//! The `ucc` program.
fn main() {}
