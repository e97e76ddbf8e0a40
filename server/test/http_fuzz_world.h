#pragma once
// Shared by the HTTP libFuzzer harnesses (docs/fuzzing.md): one in-memory
// library with the core, joint and token routes on an HttpServer that is
// never bound (requests go through Dispatch, with the daemon's query check),
// and one material with a fitted model so that evaluation routes get past
// their lookups.
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>

#include "frictiond/server/auth.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/server/routes.h"

namespace frictiond::fuzz {

struct HttpWorld {
  std::unique_ptr<FrictionLibrary> lib;
  std::unique_ptr<HttpServer> http;
  std::unique_ptr<Authenticator> auth;

  HttpWorld() {
    lib = std::make_unique<FrictionLibrary>(OpenStore(":memory:"));
    http = std::make_unique<HttpServer>();
    auth = std::make_unique<Authenticator>(
        lib->store(), http->metrics(), AuthOptions{});
    RegisterCoreRoutes(*http, *lib);
    RegisterJointRoutes(*http, *lib);
    RegisterExportRoutes(*http, *lib);
    RegisterAuthRoutes(*http, *auth, lib->store());
    InstallQueryCheck(*http);
    // A deterministic sliding stroke set: mu = 0.5 + 0.002 v + 0.01 Fn.
    std::string csv = "t_s,fn_n,ft_n,v_mm_s\n";
    unsigned state = 12345;
    for (int i = 0; i < 3000; ++i) {
      state = state * 1103515245u + 12345u;
      const double noise = ((state >> 8) % 1000) / 1000.0 - 0.5;
      const double fn = 1.0 + (i % 50) * 0.2;
      const double v = (i % 400 < 40) ? 0.0 : 5.0 + (i % 37) * 2.0;
      const double ft =
          v > 0 ? (0.5 + 0.002 * v + 0.01 * fn) * fn + 0.01 * noise : 0.2 * fn;
      csv += std::to_string(i * 0.01) + "," + std::to_string(fn) + "," +
             std::to_string(ft) + "," + std::to_string(v) + "\n";
    }
    HttpRequest r;
    r.method = "POST";
    r.path = "/v1/materials/fz-known/strokes";
    r.body = csv;
    r.remote_addr = "127.0.0.1";
    http->Dispatch(r);
  }

  /// Dispatches; a 5xx is a finding (no input may produce one).
  void Check(const HttpRequest& r) const {
    const HttpResponse out = http->Dispatch(r);
    if (out.status >= 500) std::abort();
  }
};

}  // namespace frictiond::fuzz
