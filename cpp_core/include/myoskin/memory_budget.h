// Memory budget: the core's large stages estimate what they will allocate and stop with an InputError when that
// would not fit in the memory this process may still use, instead of being killed by the kernel's out-of-memory
// killer half way (README "Limits"). Estimates are the peaks measured by benchmarks/bench_limits.py, with margin.
#pragma once
#include <cstdint>
#include <string>

namespace myoskin {

// ============================================================================
// What is available
// ============================================================================

// Bytes this process can still allocate: the least of the system's MemAvailable (/proc/meminfo), the cgroup's
// memory.max minus memory.current (cgroup v2; farms and containers cap jobs this way), RLIMIT_AS minus the address
// space in use, and the environment variable MYOSKIN_MEMORY_LIMIT (bytes, or a number with K, M or G, e.g.
// "4G": a cap on the whole process, a farm job's share) minus the resident set. UINT64_MAX when none is known.
std::uint64_t availableMemoryBytes();

// Throws InputError "<what> needs about X MiB of memory, Y MiB are available (...)" when bytes > available.
void requireMemory(std::uint64_t bytes, const std::string& what);

// ============================================================================
// Estimates (bytes, peak above what the inputs already hold)
// ============================================================================

// Muscle extraction on a skin of `vertices` vertices (measured: 0.54 KiB per vertex at 1M vertices).
std::uint64_t extractionMemoryEstimate(std::int64_t vertices);

// Hybrid weights for `muscles` muscles on `vertices` vertices (measured: ~0.2 KiB per vertex plus ~1 byte per
// vertex and muscle).
std::uint64_t hybridWeightsMemoryEstimate(std::int64_t vertices, std::int64_t muscles);

// The Skinner's packed weights: `influences` slots per vertex.
std::uint64_t skinnerMemoryEstimate(std::int64_t vertices, std::int64_t influences);

}  // namespace myoskin
