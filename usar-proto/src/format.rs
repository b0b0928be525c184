//! The three number formatters of UDK-USARSim (protocol.md §1.4).
/// Implicit float (stub).
pub fn ue_float(v: f64, out: &mut String) {
    out.push_str(&format!("{v:.4}"));
}
