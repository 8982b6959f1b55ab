//! The complementarity problem of the normal impulse shares (being written).
