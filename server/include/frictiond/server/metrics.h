#pragma once
/// @file
/// Prometheus metrics: request counts by route, method and status, and a
/// latency histogram per route. Lock-free on the hot path once a route's
/// series exist.

#include <array>
#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace frictiond {

/// One series without labels in Prometheus text format 0.0.4: its HELP and
/// TYPE lines ("gauge" or "counter") and "name value".
std::string RenderSeries(const char* name,
                         const char* type,
                         const char* help,
                         std::uint64_t value);

/// Gauges of the process's heap (glibc mallinfo2), Prometheus text:
/// frictiond_heap_in_use_bytes (allocated and not freed, mmapped blocks
/// included) and frictiond_heap_free_bytes (freed but kept by the
/// allocator's arenas). RSS growth with a flat in-use figure is the
/// allocator keeping memory, not a leak (bench/soak reports both).
std::string RenderHeapGauges();

/// Registry of request metrics. Thread-safe. Not copyable.
class Metrics {
 public:
  Metrics() = default;
  Metrics(const Metrics&) = delete;
  Metrics& operator=(const Metrics&) = delete;

  /// Records one request on `route` (a pattern such as
  /// "/v1/materials/{id}/model", never a raw path) that took `seconds`.
  void Record(const std::string& route,
              const std::string& method,
              int status,
              double seconds);
  /// Adds to a named counter (e.g. "lcm_dropped_total"), which may carry
  /// Prometheus labels: "lcm_dropped_total{reason=\"forged\"}". by = 0
  /// makes the series appear at 0.
  void Increment(const std::string& counter, std::int64_t by = 1);
  /// Prometheus text exposition format 0.0.4.
  std::string Render() const;

  /// Histogram bucket upper bounds [s].
  static constexpr std::array<double, 12> kBuckets = {0.0001,
                                                      0.00025,
                                                      0.0005,
                                                      0.001,
                                                      0.0025,
                                                      0.005,
                                                      0.01,
                                                      0.025,
                                                      0.05,
                                                      0.1,
                                                      0.5,
                                                      2.5};

 private:
  struct Series {
    std::array<std::atomic<std::uint64_t>, kBuckets.size() + 1> buckets{};
    std::atomic<std::uint64_t> count{0};
    std::atomic<std::uint64_t> sum_ns{0};
  };
  mutable std::mutex mu_;
  std::map<std::string, std::unique_ptr<Series>> latency_;  // by route
  std::map<std::string, std::unique_ptr<std::atomic<std::uint64_t>>>
      requests_;  // route|method|status
  std::map<std::string, std::unique_ptr<std::atomic<std::int64_t>>> counters_;
};

}  // namespace frictiond
