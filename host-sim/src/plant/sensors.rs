//! Encoders with index pulses and current measurement (being written).
