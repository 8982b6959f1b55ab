//! The brushed DC motor model (being written).
