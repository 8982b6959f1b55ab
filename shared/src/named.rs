//! Values with a name: the enumerated keys of the files (an impact law, a decay
//! mode, a controller state...) each name their values once, here, so that a
//! reader takes the allowed names from the type and a message lists exactly them.

/// A type whose values are few and each has a name in files, logs and outputs.
pub trait Enumerated: Copy + Sized + 'static {
    /// Every value, in the order messages and documents list them.
    const ALL: &'static [Self];

    /// The value's name as written in files and outputs.
    fn name(self) -> &'static str;

    /// The value named `name` ([`Enumerated::name`]), if any.
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|v| v.name() == name)
    }
}
