//! Simulation: generated worlds for tests, examples and the built-in demo.

pub mod boulder_field;
