// The sample wrapper's LocalSample defaults by stores (plugin/core/closure.h write_local_sample_defaults; session 33):
// written over storage full of garbage, every field must hold LocalSample{}'s value, and the wrapper's static_assert
// must count LocalSample's fields. Negative controls: each field left as garbage in turn (the bug a forgotten store
// would be) must be seen, and a struct with one more field must count one more.
#include <gtest/gtest.h>

#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "core/closure.h"

namespace {

using glimmer::Vec3;
using glimmer::plugin::LocalSample;

template <typename F>
bool same_bytes(const F &a, const F &b) {
  return std::memcmp(&a, &b, sizeof(F)) == 0;
}

// The fields of a and b that differ bit for bit (padding is not compared).
std::vector<std::string> differing_fields(const LocalSample &a, const LocalSample &b) {
  std::vector<std::string> out;
  const auto check = [&](bool same, const char *name) {
    if (!same) out.emplace_back(name);
  };
  check(same_bytes(a.wo, b.wo), "wo");
  check(same_bytes(a.f_cos, b.f_cos), "f_cos");
  check(same_bytes(a.pdf, b.pdf), "pdf");
  check(same_bytes(a.roughness, b.roughness), "roughness");
  check(same_bytes(a.eta, b.eta), "eta");
  check(same_bytes(a.label, b.label), "label");
  check(same_bytes(a.moved, b.moved), "moved");
  check(same_bytes(a.origin, b.origin), "origin");
  check(same_bytes(a.origin_Ng, b.origin_Ng), "origin_Ng");
  check(same_bytes(a.exit_lobe, b.exit_lobe), "exit_lobe");
  check(same_bytes(a.lobe_axis, b.lobe_axis), "lobe_axis");
  check(same_bytes(a.lobe_sharpness, b.lobe_sharpness), "lobe_sharpness");
#if GLIMMER_ABI_MINOR >= 7
  check(same_bytes(a.mixture_out, b.mixture_out), "mixture_out");
  check(same_bytes(a.exit_mixture, b.exit_mixture), "exit_mixture");
#endif
#if GLIMMER_ABI_MINOR >= 8
  check(same_bytes(a.state_out, b.state_out), "state_out");
  check(same_bytes(a.exit_state, b.exit_state), "exit_state");
#endif
  return out;
}

// A LocalSample in storage filled with `garbage`, then written by write_local_sample_defaults, except the bytes of
// the field at [poison_at, poison_at + poison_size), written with garbage again afterwards (a forgotten store).
struct Storage {
  alignas(LocalSample) unsigned char bytes[sizeof(LocalSample)];
};
const LocalSample &defaults_in(Storage &st, unsigned char garbage, size_t poison_at = 0, size_t poison_size = 0) {
  std::memset(st.bytes, garbage, sizeof st.bytes);
  LocalSample &s = *std::launder(reinterpret_cast<LocalSample *>(st.bytes));
  glimmer::plugin::write_local_sample_defaults(s);
  std::memset(st.bytes + poison_at, garbage, poison_size);
  return s;
}

TEST(ClosureSampleDefaults, EveryFieldHoldsLocalSampleDefaults) {
  const LocalSample reference{};
  for (unsigned char garbage : {0xab, 0x55, 0xff}) {
    Storage st;
    EXPECT_TRUE(differing_fields(defaults_in(st, garbage), reference).empty()) << int(garbage);
  }
  // Negative controls: each field (its offset and size in LocalSample) left as garbage is reported, by name.
  struct Field {
    size_t at, size;
    const char *name;
  };
  const std::vector<Field> fields = {
      {offsetof(LocalSample, wo), sizeof(Vec3), "wo"},
      {offsetof(LocalSample, f_cos), sizeof(Vec3), "f_cos"},
      {offsetof(LocalSample, pdf), sizeof(float), "pdf"},
      {offsetof(LocalSample, roughness), sizeof(float), "roughness"},
      {offsetof(LocalSample, eta), sizeof(float), "eta"},
      {offsetof(LocalSample, label), sizeof(uint32_t), "label"},
      {offsetof(LocalSample, moved), sizeof(bool), "moved"},
      {offsetof(LocalSample, origin), sizeof(Vec3), "origin"},
      {offsetof(LocalSample, origin_Ng), sizeof(Vec3), "origin_Ng"},
      {offsetof(LocalSample, exit_lobe), sizeof(bool), "exit_lobe"},
      {offsetof(LocalSample, lobe_axis), sizeof(Vec3), "lobe_axis"},
      {offsetof(LocalSample, lobe_sharpness), sizeof(float), "lobe_sharpness"},
#if GLIMMER_ABI_MINOR >= 7
      {offsetof(LocalSample, mixture_out), sizeof(void *), "mixture_out"},
      {offsetof(LocalSample, exit_mixture), sizeof(bool), "exit_mixture"},
#endif
#if GLIMMER_ABI_MINOR >= 8
      {offsetof(LocalSample, state_out), sizeof(void *), "state_out"},
      {offsetof(LocalSample, exit_state), sizeof(bool), "exit_state"},
#endif
  };
  for (const Field &f : fields) {
    Storage st;
    const std::vector<std::string> diff = differing_fields(defaults_in(st, 0xab, f.at, f.size), reference);
    EXPECT_EQ(diff, std::vector<std::string>{f.name});
  }
}

struct ThreeFields {
  Vec3 a;
  float b = 0.0f;
  bool c = false;
};
struct FourFields {  // ThreeFields and one more (a pointer, as LocalSample's buffers)
  Vec3 a;
  float b = 0.0f;
  bool c = false;
  int *d = nullptr;
};

TEST(ClosureSampleDefaults, AggregateFieldCount) {
  using glimmer::plugin::detail::aggregate_field_count;
  EXPECT_EQ(aggregate_field_count<ThreeFields>(), 3u);
  EXPECT_EQ(aggregate_field_count<FourFields>(), 4u);  // control: one more field, one more count
}

}  // namespace
