//! zeroset
