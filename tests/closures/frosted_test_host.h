// Host services for frosted glass tests and benchmarks (tests/closures/test_frosted_sg.cpp,
// benchmarks/bench_frosted_sg.cpp): the default services with trace_ray and trace_ray_closure both answered by
// one function of the caller's scene, Trace(host_data, ray, hit, hit_closure); trace_ray passes it a scratch
// closure record it then drops.
#pragma once

#include "glimmer/closure_abi.h"
#include "host/closure_instance.h"

namespace glimmer::test {

template <int (*Trace)(void *, const GlimmerRay *, GlimmerRayHit *, GlimmerHitClosure *)>
GlimmerHostServices tracing_host_services(void *host_data) {
  GlimmerHostServices services = *host::default_host_services();
  services.struct_size = sizeof(GlimmerHostServices);
  services.host_data = host_data;
  services.trace_ray = [](void *d, const GlimmerRay *r, GlimmerRayHit *h) {
    GlimmerHitClosure c{};
    c.struct_size = sizeof c;
    return Trace(d, r, h, &c);
  };
  services.trace_ray_closure = Trace;
  return services;
}

}  // namespace glimmer::test
