#include "frictiond/server/metrics.h"

#include <cstdio>
#include <sstream>

#include "frictiond/server/allocator.h"

namespace frictiond {

void Metrics::Record(const std::string& route,
                     const std::string& method,
                     int status,
                     double seconds) {
  Series* s;
  std::atomic<std::uint64_t>* r;
  const std::string key = route + '|' + method + '|' + std::to_string(status);
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto& sp = latency_[route];
    if (!sp) sp = std::make_unique<Series>();
    s = sp.get();
    auto& rp = requests_[key];
    if (!rp) rp = std::make_unique<std::atomic<std::uint64_t>>(0);
    r = rp.get();
  }
  r->fetch_add(1, std::memory_order_relaxed);
  std::size_t b = 0;
  while (b < kBuckets.size() && seconds > kBuckets[b]) ++b;
  s->buckets[b].fetch_add(1, std::memory_order_relaxed);
  s->count.fetch_add(1, std::memory_order_relaxed);
  s->sum_ns.fetch_add(static_cast<std::uint64_t>(seconds * 1e9),
                      std::memory_order_relaxed);
}

void Metrics::Increment(const std::string& counter, std::int64_t by) {
  std::atomic<std::int64_t>* c;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto& p = counters_[counter];
    if (!p) p = std::make_unique<std::atomic<std::int64_t>>(0);
    c = p.get();
  }
  c->fetch_add(by, std::memory_order_relaxed);
}

std::string Metrics::Render() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::ostringstream out;
  out << "# HELP frictiond_http_requests_total HTTP requests by route pattern, "
         "method and status.\n"
      << "# TYPE frictiond_http_requests_total counter\n";
  for (const auto& [key, v] : requests_) {
    const auto a = key.find('|');
    const auto b = key.rfind('|');
    out << "frictiond_http_requests_total{route=\"" << key.substr(0, a)
        << "\",method=\"" << key.substr(a + 1, b - a - 1) << "\",status=\""
        << key.substr(b + 1) << "\"} " << v->load() << "\n";
  }
  out << "# HELP frictiond_http_request_duration_seconds HTTP request latency "
         "by route pattern.\n"
      << "# TYPE frictiond_http_request_duration_seconds histogram\n";
  for (const auto& [route, s] : latency_) {
    std::uint64_t cum = 0;
    for (std::size_t b = 0; b <= kBuckets.size(); ++b) {
      cum += s->buckets[b].load();
      char le[32];
      if (b < kBuckets.size()) {
        std::snprintf(le, sizeof le, "%g", kBuckets[b]);
      } else {
        std::snprintf(le, sizeof le, "+Inf");
      }
      out << "frictiond_http_request_duration_seconds_bucket{route=\"" << route
          << "\",le=\"" << le << "\"} " << cum << "\n";
    }
    out << "frictiond_http_request_duration_seconds_sum{route=\"" << route
        << "\"} " << s->sum_ns.load() * 1e-9 << "\n";
    out << "frictiond_http_request_duration_seconds_count{route=\"" << route
        << "\"} " << s->count.load() << "\n";
  }
  // A counter name may carry labels ("lcm_dropped_total{reason=\"forged\"}");
  // the map is sorted, so the series of one name are adjacent and share one
  // TYPE line.
  std::string last_base;
  for (const auto& [name, v] : counters_) {
    const std::string base = name.substr(0, name.find('{'));
    if (base != last_base) out << "# TYPE frictiond_" << base << " counter\n";
    last_base = base;
    out << "frictiond_" << name << " " << v->load() << "\n";
  }
  return out.str();
}

std::string RenderSeries(const char* name,
                         const char* type,
                         const char* help,
                         std::uint64_t value) {
  return std::string("# HELP ") + name + " " + help + "\n# TYPE " + name + " " +
         type + "\n" + name + " " + std::to_string(value) + "\n";
}

std::string RenderHeapGauges() {
  const HeapStats h = ReadHeapStats();
  const std::string allocator = ToString(CurrentHeapAllocator());
  const std::string in_use_help =
      "Heap bytes allocated and not freed (" + allocator +
      (allocator == "glibc" ? ": mallinfo2 uordblks + hblkhd)."
                            : ": stats.allocated).");
  const std::string free_help =
      "Heap bytes freed but kept by the allocator (" + allocator +
      (allocator == "glibc" ? ": mallinfo2 fordblks)."
                            : ": stats.resident - stats.allocated).");
  return RenderSeries("frictiond_heap_in_use_bytes",
                      "gauge",
                      in_use_help.c_str(),
                      h.in_use) +
         RenderSeries("frictiond_heap_free_bytes",
                      "gauge",
                      free_help.c_str(),
                      h.kept_free);
}

}  // namespace frictiond
