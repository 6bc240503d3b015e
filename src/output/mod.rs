//! Writing frames: EXR with every requested AOV ([`exr`]) and PNG previews ([`png`]), each
//! file written atomically ([`atomic`]); crops merged back into a frame ([`merge`]).

pub mod atomic;
pub mod exr;
pub mod merge;
pub mod png;
