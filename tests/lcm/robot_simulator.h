#pragma once
/// @file
/// A robot that talks to frictiond over LCM (docs/lcm.md), for end-to-end
/// tests and by hand (frictiond_robot_sim): it asks for a material, and when
/// the daemon does not know it, performs the requested test strokes by
/// simulating them from a hidden truth, streams them as chunks (optionally
/// duplicated, reordered, with a chunk held back until the daemon asks for
/// it again), waits for the fitted model (paper 000, Fig. 11) and checks it
/// against the truth.
///
/// The hidden truth (testing::RobotTruth, frictiond/testing/robot_truth.h)
/// is one friction law that is both the stochastic model of paper 000 eq.
/// (1) in gross slip (mu = b0 + b1 v + b2 Fn + eps) and LuGre dynamics of
/// paper 001 (every force history comes from the LuGre simulator,
/// SimulateVelocityDriven, with theta(Fn): mu_c = b0 + b2 Fn, mu_s = mu_c +
/// static_excess, sigma2 = b1). Each requested stroke is the Fn-v sweep of
/// the plan; when the request (identification_request_v2) asks for the
/// LuGre pair, the robot appends it after a 1 s unrecorded gap: at the
/// plan's lugre_fn_n a slow triangle (quasi-static step) and the fast ones
/// (dynamic step). The received LuGre family is compared with
/// RobotTruth::ThetaAt(lugre_fn_n) (LuGreTolerances), the stochastic
/// coefficients with b0, b1, b2.

#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "frictiond/testing/robot_truth.h"

namespace frictiond::testing {

/// What the simulated robot does.
struct RobotSimOptions {
  std::string url;  ///< LCM provider URL (udpm on loopback, ttl=0)
  std::string robot = "sim-robot";
  std::string material;
  std::string fingertip = "default";
  RobotTruth truth;        ///< hidden true friction law and sweep shape
  std::uint64_t seed = 7;  ///< stroke k uses seed + k
  /// Act on identification_request_v2 and perform the LuGre pair when it
  /// asks for one. false: an old robot that acts on identification_request_v1
  /// only (sweep, no pair).
  bool request_v2 = true;
  /// Allowed errors of the received LuGre family (has_lugre) against the
  /// truth at the pair's normal force.
  LuGreTolerances lugre_tolerances;
  int chunk_samples = 250;
  bool duplicate = false;  ///< send every third chunk twice
  bool reorder = false;    ///< send chunks in a shuffled order
  bool hold_back = false;  ///< withhold chunk 1 until a resend request names it
  /// The first stroke's whole stream is lost (nothing is sent): only the
  /// robot's silence probe (the last chunk again after 2 s) and the
  /// daemon's resend requests bring it through.
  bool lose_first_stream = false;
  /// The first stroke sweeps only the lowest quarter of the requested Fn
  /// range (too little span: the daemon must ask for a follow-up).
  bool narrow_first_stroke = false;
  double timeout_s = 30.0;  ///< whole conversation
  /// The robot's LCM key (raw bytes): chunks go signed as stroke_chunk_v2
  /// on FRICTIOND_STROKE_V2, each send (resends too) with a fresh nonce; a
  /// duplicate (`duplicate`) repeats the signed bytes, which the daemon
  /// drops as replayed. Empty: unsigned stroke_chunk_v1 (the daemon must
  /// allow unsigned writes). With a key the robot also reads only signed
  /// messages from the daemon ("_SIGNED" channels, lcm_signed.h), verified
  /// with this key; forgeries are dropped (RobotSimResult::forgeries_dropped).
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
  /// Signed messages that failed verification (forged, stale, replayed,
  /// undecodable) and were dropped (robots with a key).
  int forgeries_dropped = 0;
  int follow_ups = 0;  ///< follow-up identification requests
  double last_span_pct = -1;
  int lugre_pairs = 0;               ///< strokes that ended with the LuGre pair
  double lugre_fn_n = std::nan("");  ///< normal force of the (last) pair [N]
  /// The received model's LuGre family (friction_model_v1 has_lugre,
  /// lugre_theta: mu_s, mu_c, v0_mm_s, sigma2_s_mm, sigma0_per_mm,
  /// sigma1_s_mm).
  bool has_lugre = false;
  LuGreTheta lugre_theta = LuGreTheta::Constant(std::nan(""));
  /// The hidden truth it should match: RobotTruth::ThetaAt(lugre_fn_n)
  /// (NaN when no pair was performed).
  LuGreTheta lugre_truth = LuGreTheta::Constant(std::nan(""));
  /// CompareLuGreToTruth(lugre_theta, lugre_truth, tolerances) when both
  /// exist: "" = matches; otherwise what is off. Also set when a pair was
  /// performed but no family came back.
  std::string lugre_mismatch;
  bool lugre_checked = false;    ///< a pair was performed and compared
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
