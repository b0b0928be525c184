//! Network layer: TCP sessions, the simulation driver.
