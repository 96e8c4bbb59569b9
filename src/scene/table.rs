//! A plugin family's reader table, `&[(type name, reader)]`: what the loader dispatches
//! on and what `plugins.rs` lists, so each family names its plugins once.

/// The names of a family's reader table, in its order.
pub fn names<R>(table: &[(&'static str, R)]) -> Vec<&'static str> {
    table.iter().map(|(name, _)| *name).collect()
}

/// The reader of plugin `kind` in a family's table.
pub fn reader<R: Copy>(table: &[(&'static str, R)], kind: &str) -> Option<R> {
    table
        .iter()
        .find(|(name, _)| *name == kind)
        .map(|&(_, read)| read)
}
