//! Unit tests of pose estimation.
