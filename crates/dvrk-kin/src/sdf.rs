//! SDF export with loop-closing joints. Written by a helper.
