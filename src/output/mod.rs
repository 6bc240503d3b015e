//! Writing frames: EXR with every requested AOV ([`exr`]) and PNG previews ([`png`]).

pub mod exr;
pub mod png;
