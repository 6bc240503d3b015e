//! Writing frames: EXR with every requested AOV ([`exr`]), PNG previews ([`png`]) and camera
//! files ([`cameras_json`]).

pub mod cameras_json;
pub mod exr;
pub mod png;
