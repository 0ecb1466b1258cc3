//! Process meters for benchmarks: resident memory ([`memory`]) and CPU time
//! with the hypervisor's steal ([`cpu`]). Linux figures; elsewhere they are
//! reported as absent rather than guessed.

pub mod cpu;
pub mod memory;
