#pragma once

// Hamming distances are popcounts: on x86-64 the hot functions marked PCR_POPCNT_CLONES are also
// compiled for the POPCNT instruction and picked at load time (the baseline target has none and
// would call libgcc's __popcountdi2 for each 64-bit word).
// Not under sanitizers: the ifunc resolver runs before the sanitizer runtime is up (a TSAN
// build crashed in it at start-up).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_THREAD__) && !defined(__SANITIZE_ADDRESS__)
#define PCR_POPCNT_CLONES __attribute__((target_clones("popcnt", "default")))
#else
#define PCR_POPCNT_CLONES
#endif
