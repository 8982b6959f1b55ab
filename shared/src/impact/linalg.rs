//! Small dense linear algebra (being written).
