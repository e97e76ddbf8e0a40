#include "robot_simulator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <sstream>
#include <thread>

#include <lcm/lcm-cpp.hpp>
#include <unistd.h>

#include "frictiond/coverage_progress_v1.hpp"
#include "frictiond/crypto/lcm_signing.h"
#include "frictiond/error_v1.hpp"
#include "frictiond/identification_request_v1.hpp"
#include "frictiond/identification_request_v2.hpp"
#include "frictiond/material_query_v1.hpp"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/model_update_v1.hpp"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lcm_signed.h"
#include "frictiond/stroke_chunk_v1.hpp"
#include "frictiond/stroke_chunk_v2.hpp"

namespace frictiond::testing {

namespace {

double NowS() {
  return std::chrono::duration<double>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::int64_t Utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

material_query_v1 MakeQuery(const std::string& request_id,
                            const std::string& robot,
                            const std::string& material,
                            const std::string& fingertip) {
  material_query_v1 q;
  q.utime = Utime();
  q.request_id = request_id;
  q.robot = robot;
  q.material = material;
  q.fingertip = fingertip;
  q.image_size = 0;
  return q;
}

// Collects everything the daemon says; the conversation logic polls it.
struct Inbox {
  std::vector<material_reply_v1> replies;
  std::vector<identification_request_v1> requests;
  std::vector<identification_request_v2> requests_v2;
  std::vector<coverage_progress_v1> progress;
  std::vector<model_update_v1> updates;
  std::vector<error_v1> errors;
  void OnReply(const lcm::ReceiveBuffer*,
               const std::string&,
               const material_reply_v1* m) {
    replies.push_back(*m);
  }
  void OnRequest(const lcm::ReceiveBuffer*,
                 const std::string&,
                 const identification_request_v1* m) {
    requests.push_back(*m);
  }
  void OnRequestV2(const lcm::ReceiveBuffer*,
                   const std::string&,
                   const identification_request_v2* m) {
    requests_v2.push_back(*m);
  }
  void OnProgress(const lcm::ReceiveBuffer*,
                  const std::string&,
                  const coverage_progress_v1* m) {
    progress.push_back(*m);
  }
  void OnUpdate(const lcm::ReceiveBuffer*,
                const std::string&,
                const model_update_v1* m) {
    updates.push_back(*m);
  }
  void OnError(const lcm::ReceiveBuffer*,
               const std::string&,
               const error_v1* m) {
    errors.push_back(*m);
  }
  // Signed mode (a robot with a key): only signed_message_v1 on the
  // "_SIGNED" channels is read, verified with the robot's key and decoded
  // with the bounds-checked codec; forgeries (and anything stale, replayed
  // or undecodable) are dropped and counted; copies for other robots are
  // skipped.
  std::unique_ptr<LcmSignedReceiver> verifier;
  int forgeries_dropped = 0;
  std::vector<std::string> drop_log;
  void Store(const material_reply_v1& m) { replies.push_back(m); }
  void Store(const identification_request_v1& m) { requests.push_back(m); }
  void Store(const identification_request_v2& m) { requests_v2.push_back(m); }
  void Store(const coverage_progress_v1& m) { progress.push_back(m); }
  void Store(const model_update_v1& m) { updates.push_back(m); }
  void Store(const error_v1& m) { errors.push_back(m); }
  template <class Message>
  void OnSigned(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    const std::string unsigned_channel =
        channel.substr(0, channel.size() - std::string("_SIGNED").size());
    Message m;
    const LcmVerifyResult v =
        verifier->Open(rbuf->data, rbuf->data_size, unsigned_channel, &m);
    if (v.ok()) return Store(m);
    if (v.failure == LcmVerifyFailure::kNotForMe) return;
    ++forgeries_dropped;
    if (drop_log.size() < 10)  // the first few, for the log
      drop_log.push_back(channel + ": dropped (" +
                         LcmVerifyFailureName(v.failure) + "): " + v.detail);
  }
  void SubscribeSigned(lcm::LCM& lcm,
                       const std::string& robot,
                       const std::string& key) {
    verifier = std::make_unique<LcmSignedReceiver>(
        std::map<std::string, std::string>{{robot, key}});
    lcm.subscribe(LcmSignedChannel(kLcmReplyChannel),
                  &Inbox::OnSigned<material_reply_v1>,
                  this);
    lcm.subscribe(LcmSignedChannel(kLcmIdentRequestChannel),
                  &Inbox::OnSigned<identification_request_v1>,
                  this);
    lcm.subscribe(LcmSignedChannel(kLcmIdentRequestV2Channel),
                  &Inbox::OnSigned<identification_request_v2>,
                  this);
    lcm.subscribe(LcmSignedChannel(kLcmProgressChannel),
                  &Inbox::OnSigned<coverage_progress_v1>,
                  this);
    lcm.subscribe(LcmSignedChannel(kLcmModelUpdateChannel),
                  &Inbox::OnSigned<model_update_v1>,
                  this);
    lcm.subscribe(
        LcmSignedChannel(kLcmErrorChannel), &Inbox::OnSigned<error_v1>, this);
  }
  void SubscribeAll(lcm::LCM& lcm) {
    lcm.subscribe(kLcmReplyChannel, &Inbox::OnReply, this);
    lcm.subscribe(kLcmIdentRequestChannel, &Inbox::OnRequest, this);
    lcm.subscribe(kLcmIdentRequestV2Channel, &Inbox::OnRequestV2, this);
    lcm.subscribe(kLcmProgressChannel, &Inbox::OnProgress, this);
    lcm.subscribe(kLcmModelUpdateChannel, &Inbox::OnUpdate, this);
    lcm.subscribe(kLcmErrorChannel, &Inbox::OnError, this);
  }
};

// What a robot reads from identification_request_v1 or _v2.
struct Request {
  std::int64_t job_id = 0;
  int stroke = 0;
  bool follow_up = false;
  double fn_min_n = 0, fn_max_n = 0, v_min_mm_s = 0, v_max_mm_s = 0;
  bool lugre_pair = false;
  LuGrePairShape pair;
};

// The fields v1 and v2 share (v2 is v1 plus the LuGre pair).
template <typename Message>
Request FromCommonFields(const Message& r) {
  Request q;
  q.job_id = r.job_id;
  q.stroke = r.stroke;
  q.follow_up = r.follow_up;
  q.fn_min_n = r.fn_min_n;
  q.fn_max_n = r.fn_max_n;
  q.v_min_mm_s = r.v_min_mm_s;
  q.v_max_mm_s = r.v_max_mm_s;
  return q;
}

Request FromV1(const identification_request_v1& r) {
  return FromCommonFields(r);
}

Request FromV2(const identification_request_v2& r) {
  Request q = FromCommonFields(r);
  q.lugre_pair = r.lugre_pair;
  if (r.lugre_pair) {
    q.pair.fn_n = r.lugre_fn_n;
    q.pair.slow_accel_mm_s2 = r.lugre_slow_accel_mm_s2;
    q.pair.slow_peak_mm_s = r.lugre_slow_peak_mm_s;
    q.pair.fast_strokes = r.lugre_fast_strokes;
    q.pair.fast_accel_mm_s2 = r.lugre_fast_accel_mm_s2;
    q.pair.fast_peak_mm_s = r.lugre_fast_peak_mm_s;
    q.pair.rest_s = r.lugre_rest_s;
  }
  return q;
}

// The pair's numbers must make a stroke the robot can perform.
bool CheckPair(const LuGrePairShape& p, std::string* why) {
  const bool ok = p.fn_n > 0 && p.slow_accel_mm_s2 > 0 &&
                  p.slow_peak_mm_s > 0 && p.fast_strokes >= 0 &&
                  p.fast_strokes <= 100 && p.fast_accel_mm_s2 > 0 &&
                  p.fast_peak_mm_s > 0 && p.rest_s > 0 &&
                  p.slow_peak_mm_s / p.slow_accel_mm_s2 < 1000;
  if (!ok) *why = "identification_request_v2: unusable LuGre pair";
  return ok;
}

}  // namespace

std::string MakeTestLcmUrl(int salt) {
  const int port = 20000 + (static_cast<int>(getpid()) * 7 + salt) % 30000;
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
}

bool CheckLcmLoopback(const std::string& url, std::string* why) {
  const std::string need =
      "LCM udpm needs multicast on loopback: run inside `unshare -n` with `ip "
      "link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 "
      "dev lo` (deploy/test.sh does this)";
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    *why = "cannot create LCM provider " + url + ". " + need;
    return false;
  }
  struct Probe {
    int received = 0;
    void On(const lcm::ReceiveBuffer*, const std::string&) { ++received; }
  } probe;
  lcm.subscribe("FRICTIOND_TEST_PROBE", &Probe::On, &probe);
  const char byte = 1;
  for (int attempt = 0; attempt < 5 && probe.received == 0; ++attempt) {
    lcm.publish("FRICTIOND_TEST_PROBE", &byte, 1);
    lcm.handleTimeout(200);
  }
  if (probe.received == 0) {
    *why = "a message published on " + url + " did not come back. " + need;
    return false;
  }
  return true;
}

int QueryMaterialOnce(const std::string& url,
                      const std::string& material,
                      const std::string& fingertip,
                      std::int64_t* job_id,
                      double timeout_s) {
  lcm::LCM lcm(url);
  if (!lcm.good()) return -1;
  Inbox inbox;
  inbox.SubscribeAll(lcm);
  const std::string request_id = "once-" + std::to_string(Utime());
  const material_query_v1 q =
      MakeQuery(request_id, "sim-robot", material, fingertip);
  lcm.publish(kLcmQueryChannel, &q);
  const double deadline = NowS() + timeout_s;
  *job_id = 0;
  int status = -1;
  double last_query_s = NowS();
  while (NowS() < deadline) {
    lcm.handleTimeout(50);
    if (status < 0 && NowS() - last_query_s > 1.0) {
      lcm.publish(kLcmQueryChannel, &q);  // UDP may lose a datagram
      last_query_s = NowS();
    }
    for (const auto& r : inbox.replies) {
      if (r.request_id == request_id) {
        status = r.status;
        *job_id = r.job_id;
      }
    }
    if (status == material_reply_v1::STATUS_KNOWN ||
        status == material_reply_v1::STATUS_ERROR)
      return status;
    if (status == material_reply_v1::STATUS_UNKNOWN) {
      for (const auto& r : inbox.requests) {
        if (r.job_id == *job_id) return status;
      }
    }
  }
  return status;
}

RobotSimResult RunRobotSimulation(const RobotSimOptions& o) {
  RobotSimResult res;
  auto log = [&](const std::string& s) { res.log.push_back(s); };
  auto fail = [&](const std::string& why) {
    res.ok = false;
    res.why = why;
    return res;
  };
  lcm::LCM lcm(o.url);
  if (!lcm.good()) return fail("cannot create LCM provider " + o.url);
  Inbox inbox;
  if (o.key.empty())
    inbox.SubscribeAll(lcm);
  else
    inbox.SubscribeSigned(lcm, o.robot, o.key);
  // Unique per robot and material: robots sharing a name (and key) may ask
  // for different materials at once.
  const std::string request_id =
      (o.robot + "-" + o.material).substr(0, 125) + "-q1";
  const material_query_v1 q =
      MakeQuery(request_id, o.robot, o.material, o.fingertip);
  lcm.publish(kLcmQueryChannel, &q);
  log("query " + o.material);

  // Chunks of the stroke being streamed, by seq, for resends.
  std::vector<stroke_chunk_v1> chunks;
  // Sends chunk k: signed anew (fresh utime and nonce) when the robot has a
  // key; `repeat_last` re-publishes the previous bytes unchanged (a network
  // duplicate).
  std::string last_bytes;
  auto send = [&](int k, bool repeat_last) {
    ++res.chunks_sent;
    if (o.key.empty()) {
      lcm.publish(kLcmStrokeChannel, &chunks[k]);
      return;
    }
    if (!repeat_last) {
      const stroke_chunk_v1& c = chunks[k];
      stroke_chunk_v2 s;
      s.job_id = c.job_id;
      s.stroke = c.stroke;
      s.robot = c.robot;
      s.material = c.material;
      s.fingertip = c.fingertip;
      s.seq = c.seq;
      s.total_chunks = c.total_chunks;
      s.last = c.last;
      s.n_samples = c.n_samples;
      s.t_s = c.t_s;
      s.fn_n = c.fn_n;
      s.ft_n = c.ft_n;
      s.v_mm_s = c.v_mm_s;
      SignLcmMessage(&s, o.key);
      last_bytes.assign(static_cast<std::size_t>(s.getEncodedSize()), '\0');
      s.encode(last_bytes.data(), 0, static_cast<int>(last_bytes.size()));
    }
    lcm.publish(kLcmSignedStrokeChannel,
                last_bytes.data(),
                static_cast<unsigned>(last_bytes.size()));
  };
  int current_stroke = -1;
  int held_back = -1;
  std::size_t seen_requests = 0, seen_progress = 0, seen_errors = 0;
  std::mt19937_64 rng(o.seed * 31 + 1);
  const double deadline = NowS() + o.timeout_s;
  bool got_reply = false;
  double last_query_s = NowS();
  // Whether the daemon said anything about the current stroke since it was
  // streamed, and when the stream (or the last probe) went out: a robot
  // that hears nothing at all (every chunk lost, e.g. a burst of other
  // traffic overflowing the receive queue) sends the last chunk again; it
  // carries the total, so the daemon then asks for every missing seq
  // (docs/lcm.md "Lost chunks").
  bool heard_stroke = true;
  double probe_s = 0.0;
  constexpr double kSilenceS = 2.0;
  while (NowS() < deadline) {
    lcm.handleTimeout(20);
    if (!got_reply && NowS() - last_query_s > 1.0) {
      // UDP may lose a datagram: ask again (the daemon answers idempotently).
      lcm.publish(kLcmQueryChannel, &q);
      last_query_s = NowS();
      log("query resent");
    }
    if (!got_reply) {
      for (const auto& r : inbox.replies) {
        if (r.request_id != request_id) continue;
        got_reply = true;
        res.reply_status = r.status;
        res.job_id = r.job_id;
        log("reply status " + std::to_string(r.status) + ": " + r.reason);
        if (r.status != material_reply_v1::STATUS_UNKNOWN)
          return fail("expected an unknown material, got status " +
                      std::to_string(r.status) + " (" + r.reason + ")");
      }
      if (!got_reply) continue;
    }
    for (; seen_errors < inbox.errors.size(); ++seen_errors) {
      const error_v1& e = inbox.errors[seen_errors];
      if (e.job_id == res.job_id || e.request_id == request_id)
        return fail("daemon rejected " + e.message_type + " (" + e.field +
                    "): " + e.reason);
    }
    // A (follow-up) identification request: perform and stream the stroke.
    std::vector<Request> fresh;
    if (o.request_v2) {
      for (; seen_requests < inbox.requests_v2.size(); ++seen_requests)
        fresh.push_back(FromV2(inbox.requests_v2[seen_requests]));
    } else {
      for (; seen_requests < inbox.requests.size(); ++seen_requests)
        fresh.push_back(FromV1(inbox.requests[seen_requests]));
    }
    for (const Request& r : fresh) {
      if (r.job_id != res.job_id || r.stroke <= current_stroke) continue;
      current_stroke = r.stroke;
      if (r.follow_up) ++res.follow_ups;
      double fn_max_n = r.fn_max_n;
      if (o.narrow_first_stroke && r.stroke == 0)
        fn_max_n = r.fn_min_n + 0.25 * (r.fn_max_n - r.fn_min_n);
      StrokeData d;
      try {
        d = SimulateTruthSweep(o.truth,
                               r.fn_min_n,
                               fn_max_n,
                               r.v_min_mm_s,
                               r.v_max_mm_s,
                               o.seed + r.stroke);
      } catch (const std::exception& e) {
        return fail(std::string("cannot simulate the sweep: ") + e.what());
      }
      std::ostringstream s;
      s << "stroke " << r.stroke << (r.follow_up ? " (follow-up)" : "")
        << ": fn " << r.fn_min_n << "-" << fn_max_n << " N, v " << r.v_min_mm_s
        << "-" << r.v_max_mm_s << " mm/s";
      if (r.lugre_pair) {
        std::string why;
        if (!CheckPair(r.pair, &why)) return fail(why);
        // The pair after a 1 s unrecorded gap, in the same stroke.
        StrokeData p;
        try {
          p = SimulateTruthLuGrePair(o.truth, r.pair, o.seed + r.stroke);
        } catch (const std::exception& e) {
          return fail(std::string("cannot simulate the LuGre pair: ") +
                      e.what());
        }
        const double shift = d.t_s.back() + 1.0;
        for (double& t : p.t_s) t += shift;
        d.Append(p);
        ++res.lugre_pairs;
        res.lugre_fn_n = r.pair.fn_n;
        res.lugre_truth = o.truth.ThetaAt(r.pair.fn_n);
        s << " + LuGre pair at " << r.pair.fn_n << " N (1 slow, "
          << r.pair.fast_strokes << " fast)";
      }
      s << ", " << d.size() << " samples";
      log(s.str());
      chunks.clear();
      const int n = static_cast<int>(d.size());
      const int total = (n + o.chunk_samples - 1) / o.chunk_samples;
      for (int k = 0; k < total; ++k) {
        stroke_chunk_v1 c;
        c.utime = Utime();
        c.job_id = res.job_id;
        c.stroke = r.stroke;
        c.robot = o.robot;
        c.material = o.material;
        c.fingertip = o.fingertip;
        c.seq = k;
        // Announce the total only in the last chunk, as a streaming robot
        // that does not know the length in advance would.
        c.total_chunks = k == total - 1 ? total : 0;
        c.last = k == total - 1;
        const int b = k * o.chunk_samples;
        const int e = std::min(n, b + o.chunk_samples);
        c.t_s.assign(d.t_s.begin() + b, d.t_s.begin() + e);
        c.fn_n.assign(d.fn_n.begin() + b, d.fn_n.begin() + e);
        c.ft_n.assign(d.ft_n.begin() + b, d.ft_n.begin() + e);
        c.v_mm_s.assign(d.v_mm_s.begin() + b, d.v_mm_s.begin() + e);
        c.n_samples = e - b;
        chunks.push_back(std::move(c));
      }
      std::vector<int> order(total);
      for (int k = 0; k < total; ++k) order[k] = k;
      if (o.reorder) std::shuffle(order.begin(), order.end(), rng);
      held_back = o.hold_back && total > 2 ? 1 : -1;
      const bool lose = o.lose_first_stream && res.strokes_sent == 0;
      for (int k : order) {
        if (k == held_back || lose) continue;
        send(k, false);
        if (o.duplicate && k % 3 == 0) send(k, true);
        // Pace the stream a little (a robot streams as it samples): udpm
        // drops datagrams that overflow the receiver's socket buffer, which
        // the resend requests then repair.
        std::this_thread::sleep_for(std::chrono::microseconds(300));
      }
      ++res.strokes_sent;
      heard_stroke = false;
      probe_s = NowS();
    }
    if (!heard_stroke && !chunks.empty() && NowS() - probe_s > kSilenceS) {
      send(static_cast<int>(chunks.size()) - 1, false);
      probe_s = NowS();
      log("no word on stroke " + std::to_string(current_stroke) +
          ": last chunk sent again");
    }
    for (; seen_progress < inbox.progress.size(); ++seen_progress) {
      const coverage_progress_v1& p = inbox.progress[seen_progress];
      if (p.job_id != res.job_id) continue;
      if (p.stroke == current_stroke) heard_stroke = true;
      if (p.span_pct >= 0) res.last_span_pct = p.span_pct;
      if (p.state != "stroking" || p.n_missing > 0 || p.span_pct >= 0)
        log("progress " + p.state + " stroke " + std::to_string(p.stroke) +
            " missing " + std::to_string(p.n_missing) + ": " + p.detail);
      if (p.n_missing > 0 && p.stroke == current_stroke) {
        ++res.resend_requests;
        for (int seq : p.missing_seqs) {
          if (seq >= 0 && seq < static_cast<int>(chunks.size())) {
            send(seq, false);
          }
        }
      }
      if (p.state == "failed") return fail("job failed: " + p.detail);
      if (p.state == "fitted") res.model_version = p.model_version;
    }
    if (res.model_version > 0) {
      for (const auto& u : inbox.updates) {
        if (u.job_id != res.job_id || u.model.version != res.model_version)
          continue;
        for (int i = 0; i < u.model.n_terms; ++i) {
          res.coefficients[u.model.term_names[i]] = u.model.coefficients[i];
          res.std_errors[u.model.term_names[i]] = u.model.std_errors[i];
        }
        res.sigma_eps = u.model.sigma_eps;
        res.has_lugre = u.model.has_lugre;
        if (u.model.has_lugre)
          for (int i = 0; i < 6; ++i)
            res.lugre_theta[i] = u.model.lugre_theta[i];
        if (res.lugre_pairs > 0) {
          res.lugre_checked = true;
          res.lugre_mismatch =
              res.has_lugre
                  ? CompareLuGreToTruth(
                        res.lugre_theta, res.lugre_truth, o.lugre_tolerances)
                  : "the model has no LuGre family although the "
                    "pair was performed";
        }
        res.ok = true;
        res.forgeries_dropped = inbox.forgeries_dropped;
        for (const std::string& d : inbox.drop_log) log(d);
        log("model_update version " + std::to_string(u.model.version));
        return res;
      }
    }
  }
  return fail(got_reply ? "timed out waiting for the fitted model"
                        : "timed out waiting for the reply");
}

}  // namespace frictiond::testing
