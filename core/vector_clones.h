// RIGPORT_VECTOR_CLONES: compile a hot loop twice, for AVX2 and for baseline
// x86-64, and pick one at load time (GCC target_clones). Neither clone may
// contract a*b+c into FMA ("avx2" does not enable it, and -std=c++20 sets
// -ffp-contract=off), so a loop whose lanes each compute their own result in
// a fixed order gives bit-identical results on every machine.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define RIGPORT_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define RIGPORT_VECTOR_CLONES
#endif
