//! host-sim: the vibro driver's simulator, impact analysis and tuning tool.
#![warn(missing_docs)]
