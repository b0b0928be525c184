//! The three number formatters of UDK-USARSim (protocol.md §1.4).
