//! All integration tests of this crate in one binary: one link instead of one per file,
//! which keeps the build small and fast (each file is a module, named as before).

mod binary;
mod cli_docs;
mod commands;
