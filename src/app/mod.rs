//! Application code of the `clipsat` binary, not library API: the subcommands ([`cmd`]), the PNG plots
//! they write ([`plot`]) and the interactive view's key map ([`view_keys`]).

pub(crate) mod cmd;
pub(crate) mod plot;
pub(crate) mod progress;
#[cfg(feature = "view")]
pub(crate) mod view_keys;
