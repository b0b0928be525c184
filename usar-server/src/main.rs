//! The `usar-server` program.
fn main() {}
