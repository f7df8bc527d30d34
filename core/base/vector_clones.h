// RIGPORT_VECTOR_CLONES: compile a hot loop three times, for AVX-512F, AVX2
// and baseline x86-64, and pick one at load time (GCC target_clones). No
// clone may contract a*b+c into FMA: AVX-512F has FMA instructions and GCC
// contracts by default even under -std=c++20, so every target is compiled
// with -ffp-contract=off (rigport_target_defaults). A loop whose lanes each
// compute their own result in a fixed order then gives bit-identical results
// on every machine (Tps.BatchEvaluationIsBitIdenticalToScalarReference; it
// failed with the AVX-512F clone before the flag). The AVX-512F clone halves
// TPS apply on the project's VM (AMD EPYC, Zen 5: full-width 512-bit units).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define RIGPORT_VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define RIGPORT_VECTOR_CLONES
#endif
