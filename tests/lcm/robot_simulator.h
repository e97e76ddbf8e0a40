#pragma once
/// @file
/// A robot that talks to frictiond over LCM (docs/lcm.md), for end-to-end
/// tests and by hand (frictiond_robot_sim): it asks for a material, and when
/// the daemon does not know it, performs the requested test strokes by
/// simulating them from a hidden true stochastic model (paper 000 eq. (1),
/// testing::SimulateStrokes), streams them as chunks (optionally
/// duplicated, reordered, with a chunk held back until the daemon asks for
/// it again), and waits for the fitted model (paper 000, Fig. 11).

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "frictiond/testing/stroke_simulator.h"

namespace frictiond::testing {

/// What the simulated robot does.
struct RobotSimOptions {
  std::string url;  ///< LCM provider URL (udpm on loopback, ttl=0)
  std::string robot = "sim-robot";
  std::string material;
  std::string fingertip = "default";
  SimulationSpec truth;    ///< hidden true model and stroke shape
  std::uint64_t seed = 7;  ///< stroke k uses seed + k
  int chunk_samples = 250;
  bool duplicate = false;  ///< send every third chunk twice
  bool reorder = false;    ///< send chunks in a shuffled order
  bool hold_back = false;  ///< withhold chunk 1 until a resend request names it
  /// The first stroke sweeps only the lowest quarter of the requested Fn
  /// range (too little span: the daemon must ask for a follow-up).
  bool narrow_first_stroke = false;
  double timeout_s = 30.0;  ///< whole conversation
  /// The robot's LCM key (raw bytes): chunks go signed as stroke_chunk_v2
  /// on FRICTIOND_STROKE_V2, each send (resends too) with a fresh nonce; a
  /// duplicate (`duplicate`) repeats the signed bytes, which the daemon
  /// drops as replayed. Empty: unsigned stroke_chunk_v1 (the daemon must
  /// allow unsigned writes).
  std::string key;
};

/// What happened.
struct RobotSimResult {
  bool ok = false;
  std::string why;  ///< failure reason
  std::int64_t job_id = 0;
  int reply_status = -1;  ///< of the first reply (material_reply_v1 status)
  int model_version = 0;  ///< fitted version
  std::map<std::string, double> coefficients;  ///< by term name
  std::map<std::string, double> std_errors;
  double sigma_eps = 0.0;
  int strokes_sent = 0;
  int chunks_sent = 0;
  int resend_requests = 0;  ///< progress messages naming missing seqs
  int follow_ups = 0;       ///< follow-up identification requests
  double last_span_pct = -1;
  std::vector<std::string> log;  ///< one line per event, for failure output
};

/// Runs the whole conversation (query -> strokes -> model).
RobotSimResult RunRobotSimulation(const RobotSimOptions& options);

/// Sends one query and waits for the reply (and, when unknown, the
/// identification request). Returns the reply status, or -1 on timeout;
/// *job_id gets the job (0 when none).
int QueryMaterialOnce(const std::string& url,
                      const std::string& material,
                      const std::string& fingertip,
                      std::int64_t* job_id,
                      double timeout_s = 5.0);

/// True when LCM over `url` works here (a message published is received
/// back); otherwise *why says what the machine needs.
bool CheckLcmLoopback(const std::string& url, std::string* why);

/// "udpm://239.255.76.67:PORT?ttl=0" with a port derived from the process
/// id and `salt`, so that tests running at the same time do not share it.
std::string MakeTestLcmUrl(int salt);

}  // namespace frictiond::testing
