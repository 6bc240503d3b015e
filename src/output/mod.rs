//! Writing frames: EXR with every requested AOV ([`exr`]), PNG previews ([`png`]) and camera
//! files ([`cameras_json`]), each file written atomically ([`atomic`]); crops merged back into a
//! frame ([`merge`]).

pub mod atomic;
pub mod cameras_json;
pub mod exr;
pub mod exr_stream;
pub mod interrupt;
pub mod merge;
pub mod png;
pub mod png_stream;
