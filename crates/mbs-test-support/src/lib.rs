//! What the tests of every mbs crate share and no user needs: seeded
//! mutations of valid files for the readers' fuzz tests, a reader of the
//! TensorBoard event files training writes, and file-tree helpers. A
//! dev-dependency only: nothing in a build of the tools links it.

pub mod events;
pub mod files;
pub mod mutation;
