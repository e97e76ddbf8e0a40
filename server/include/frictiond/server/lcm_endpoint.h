#pragma once
/// @file
/// The daemon's LCM endpoint (docs/lcm.md): the workflow of paper 000,
/// Fig. 11 over LCM, beside HTTP and on the same FrictionLibrary core.
/// - material_query_v1 -> material_reply_v1 with the model, or "unknown"
///   plus an identification_request_v1 (the job is recorded in the Store);
/// - stroke_chunk_v2 (signed: HMAC-SHA256 per robot key, timestamp, nonce;
///   forged, stale, replayed or unknown-robot messages are dropped and
///   counted) or, only with security.allow_unsigned, stroke_chunk_v1
///   -> reassembled (StrokeReassembler), coverage checked
///   (paper 000 III-E, Fig. 10), ingested through
///   FrictionLibrary::IngestStrokes (the HTTP upload's validation), with
///   coverage_progress_v1 along the way, a follow-up request when the span
///   is too small, and model_update_v1 for every new model version;
/// - every rejected message gets an error_v1 naming the field; nothing of it
///   is stored.
/// One thread runs lcm handleTimeout in a loop; no exception leaves it.
/// Available when built with FRICTIOND_WITH_LCM.

#include <cstddef>
#include <memory>
#include <string>

#include "frictiond/server/lcm_auth.h"
#include "frictiond/server/library.h"
#include "frictiond/server/metrics.h"
#include "frictiond/server/routes.h"
#include "frictiond/server/stroke_reassembler.h"

namespace frictiond {

namespace internal {
class LcmEndpointImpl;
}  // namespace internal

/// Options of the LCM endpoint.
struct LcmEndpointOptions {
  /// LCM provider URL, e.g. "udpm://239.255.76.67:7667?ttl=0".
  std::string url;
  /// Chunk limits and resend/give-up timing.
  ReassemblerOptions reassembly;
  /// Longest wait in one handleTimeout call [ms] (bounds the stop latency
  /// and the resend timer resolution).
  int poll_ms = 20;
  /// Strokes per job before it fails for too little span coverage.
  int max_strokes_per_job = 5;
  /// Recognition hook for queries with an image (empty: such queries are
  /// rejected). The daemon passes the one its HTTP routes use.
  RecognizeImageFn recognize;
  /// Keys and checks of signed writes (stroke_chunk_v2), and whether
  /// unsigned stroke_chunk_v1 is accepted (docs/lcm.md "Signed writes").
  LcmSecurityOptions security;
  /// Where dropped writes are counted (frictiond_lcm_dropped_total{reason})
  /// and accepted signed ones (frictiond_lcm_signed_accepted_total); null:
  /// not counted. Must outlive the endpoint.
  Metrics* metrics = nullptr;
  /// Names this daemon in identification-job claims (Store::ClaimJob), so
  /// that in a fleet one daemon acts on a job. Stable across restarts of the
  /// same daemon (the daemon passes host:port); empty: host:pid:random.
  std::string worker_id;
};

/// The endpoint. Not copyable or movable.
class LcmEndpoint {
 public:
  /// @throws std::invalid_argument for bad options, std::runtime_error when
  /// the LCM provider cannot be created (e.g. no multicast route).
  LcmEndpoint(FrictionLibrary& library, LcmEndpointOptions options);
  ~LcmEndpoint();
  LcmEndpoint(const LcmEndpoint&) = delete;
  LcmEndpoint& operator=(const LcmEndpoint&) = delete;

  /// Starts the handling thread (no-op when running).
  void Start();
  /// Stops and joins it (any thread except the handling one; idempotent).
  void Stop();

  /// Handles one message as if the LCM provider had received `size` bytes
  /// on `channel` (FRICTIOND_QUERY_V1, _STROKE_V1 or _STROKE_V2; others are
  /// ignored), on the calling thread, then runs due reassembly events and
  /// drains what the endpoint published. Drives the handlers without
  /// sockets (fuzzing, tests) with the provider "memq://". Call only while
  /// the handling thread is not running. Never throws.
  void HandleMessage(const std::string& channel,
                     const void* data,
                     std::size_t size);

 private:
  std::unique_ptr<internal::LcmEndpointImpl> impl_;
};

/// True when this build has the LCM endpoint (FRICTIOND_WITH_LCM).
bool HaveLcmEndpoint();

}  // namespace frictiond
