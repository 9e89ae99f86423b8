//! supervision (in progress)
