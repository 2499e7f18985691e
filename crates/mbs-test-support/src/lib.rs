//! What the tests of every mbs crate share and no user needs: seeded
//! mutations of valid files for the readers' fuzz tests, a reader of the
//! TensorBoard event files training writes, file-tree helpers, and special
//! files (devices, FIFOs, sockets) that writers must refuse. A
//! dev-dependency only: nothing in a build of the tools links it.

pub mod events;
pub mod files;
pub mod mutation;
#[cfg(unix)]
pub mod special;
