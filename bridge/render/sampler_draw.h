// The vector draws of the sampler (sampler_draw.cpp): get_vertex's and get_path_start's values computed with
// AVX2, the same floats bit for bit as the scalar code in sampler.h. A draw's six (or seven) values each need
// a seed multiply, a four-round Laine-Karras permutation (Burley 2020, "Practical Hash-based Owen
// Scrambling", JCGT 9(4), sec. 3) and the float of the reversed bits; the vector draw does them in the lanes
// of one 256-bit register: vpmulld for the seeds and the rounds, vpshufb for the byte order and the bit
// reversal of the three bytes that reach the float, one exact conversion and scale. The set's seed hash and its
// index shuffle stay scalar (shared with the scalar code); the six Sobol words come from eight 32-byte
// nibble-row loads straight into the vector (4 KB of table), vertex 0's light pair from its pair-table word.
//
// Dispatch: the variant is chosen once at start-up (CPU support, and GLIMMER_SAMPLER_DRAW=scalar forces the
// scalar code), and read by PixelSampler::get_vertex / get_path_start, which call the whole draw: a
// target("avx2") function cannot be inlined into the baseline x86-64 code around it. A binary built for
// baseline x86-64 runs the scalar code on CPUs without AVX2.
#pragma once

#include <cstdint>

#include "render/sampler.h"

namespace glimmer::render::sampler_draw {

// Whether this CPU (and this build) can run a variant; the scalar code always can.
bool supported(Variant variant);
// The variant chosen at start-up.
Variant startup_choice();
// Test hook: make `variant` the active one (it must be supported); returns the one active before.
Variant set_active(Variant variant);
const char *name(Variant variant);

// Test hook, the vector kernel alone: out[k] = reversed_to_unit_float(laine_karras_permutation(words[k],
// seeds[k])) for the 8 lanes, with the round constants `rounds` (the production draws use
// kLaineKarrasRounds; a test passes wrong ones as a negative control, or zeros with zero seeds to check the
// in-vector float alone). Requires supported(Variant::kAvx2).
void scramble_to_floats_avx2(const uint32_t (&words)[8], const uint32_t (&seeds)[8], const uint32_t (&rounds)[4],
                             float (&out)[8]);

}  // namespace glimmer::render::sampler_draw
