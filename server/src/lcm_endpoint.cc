// The daemon's LCM endpoint (lcm_endpoint.h, docs/lcm.md): paper 000,
// Fig. 11 (library lookup, test stroke, identification, fleet update) as a
// protocol beside HTTP, sharing FrictionLibrary.
#include "frictiond/server/lcm_endpoint.h"

#include <stdexcept>

#ifdef FRICTIOND_HAVE_LCM

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <iostream>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <unistd.h>

#include "frictiond/coverage_progress_v1.hpp"
#include "frictiond/crypto/lcm_signing.h"
#include "frictiond/error_v1.hpp"
#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/span_coverage.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/identification_request_v1.hpp"
#include "frictiond/identification_request_v2.hpp"
#include "frictiond/material_query_v1.hpp"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/model_update_v1.hpp"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lcm_codec.h"
#include "frictiond/proto/lcm_signed.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/stroke_chunk_v1.hpp"
#include "frictiond/stroke_chunk_v2.hpp"

namespace frictiond {

using nlohmann::json;

namespace {

constexpr std::size_t kMaxTextField = 128;
// Job claims are renewed this often while a job's chunks arrive (the store
// lets another daemon take a claim not renewed for 60 s).
constexpr double kClaimRenewS = 10.0;

std::int64_t NowUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double NowMonotonicS() {
  return std::chrono::duration<double>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// The field a validation message names: the text before " = " or ":".
std::string FieldOf(const std::string& message) {
  const std::size_t eq = message.find(" = ");
  const std::size_t colon = message.find(':');
  return message.substr(0, std::min(eq, colon));
}

// Job whose ingest is running on this thread, for the model listener.
thread_local std::int64_t tl_ingesting_job = 0;

/// Encodes a model version as friction_model_v1.
friction_model_v1 ToLcm(const CachedModel& m) {
  friction_model_v1 out;
  out.material = m.set.material;
  out.fingertip = m.set.fingertip;
  out.version = m.set.version;
  out.created_at = m.set.created_at;
  out.n_terms = 0;
  out.sigma_eps = out.r2 = out.mu_coulomb = std::nan("");
  out.likelihood_c1 = out.likelihood_c2 = std::nan("");
  out.samples = 0;
  out.n_quantiles = 0;
  if (m.set.stochastic) {
    const StochasticFrictionModel& s = *m.set.stochastic;
    out.n_terms = static_cast<int32_t>(s.mu.terms.size());
    for (std::size_t i = 0; i < s.mu.terms.size(); ++i) {
      out.term_names.push_back(s.mu.terms[i].Name());
      out.coefficients.push_back(static_cast<Eigen::Index>(i) < s.mu.beta.size()
                                     ? s.mu.beta[i]
                                     : std::nan(""));
      out.std_errors.push_back(
          static_cast<Eigen::Index>(i) < s.mu.std_err.size() ? s.mu.std_err[i]
                                                             : std::nan(""));
    }
    out.sigma_eps = s.mu.sigma_eps;
    out.r2 = s.mu.r2;
    out.samples = s.mu.samples;
    const std::vector<double>& levels = EpsQuantileLevels();
    if (s.mu.eps_quantiles.size() == levels.size()) {
      out.n_quantiles = static_cast<int32_t>(levels.size());
      out.eps_levels = levels;
      out.eps_quantiles = s.mu.eps_quantiles;
    }
    out.mu_coulomb = s.mu_coulomb;
    if (s.likelihood.valid) {
      out.likelihood_c1 = s.likelihood.c1;
      out.likelihood_c2 = s.likelihood.c2;
    }
  }
  out.has_lugre = false;
  for (double& x : out.lugre_theta) x = std::nan("");
  if (auto it = m.set.other.find(kLuGreFamilyKey); it != m.set.other.end()) {
    try {
      const LuGreFamily f = LuGreFromJson(*it);
      for (int i = 0; i < 6; ++i) out.lugre_theta[i] = f.theta[i];
      out.has_lugre = true;
    } catch (const std::exception&) {
      // A family this build cannot read is left out of the LCM message.
    }
  }
  return out;
}

}  // namespace

namespace internal {

/// Publishes on an LCM instance from any thread, until closed (the model
/// listener registered with the library may outlive the endpoint).
class LcmPublisher {
 public:
  explicit LcmPublisher(lcm::LCM* lcm) : lcm_(lcm) {}
  template <class Message>
  void Publish(const char* channel, const Message& message) {
    std::lock_guard<std::mutex> lock(mu_);
    if (lcm_) lcm_->publish(channel, &message);
  }
  void Close() {
    std::lock_guard<std::mutex> lock(mu_);
    lcm_ = nullptr;
  }
  /// A message to robots: signed (signed_message_v1 on "<channel>_SIGNED")
  /// once per key of `keys` (key id, key), and unsigned on `channel` only
  /// when `send_unsigned`.
  template <class Message>
  void PublishToRobots(
      const char* channel,
      const Message& message,
      const std::vector<std::pair<std::string, std::string>>& keys,
      bool send_unsigned) {
    if (send_unsigned) Publish(channel, message);
    if (keys.empty()) return;
    const std::string bytes = EncodeLcm(message);
    const std::string signed_channel = LcmSignedChannel(channel);
    for (const auto& [id, key] : keys)
      Publish(signed_channel.c_str(), SignLcmPayload(bytes, channel, id, key));
  }

 private:
  std::mutex mu_;
  lcm::LCM* lcm_;
};

/// "host:pid:random" naming this daemon in job claims.
std::string MakeWorkerId() {
  char host[256] = {0};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::random_device rd;
  return std::string(host) + ":" + std::to_string(::getpid()) + ":" +
         std::to_string(rd() % 1000000);
}

class LcmEndpointImpl {
 public:
  LcmEndpointImpl(FrictionLibrary& library, LcmEndpointOptions options)
      : library_(library),
        options_(std::move(options)),
        lcm_(options_.url),
        reassembler_(options_.reassembly),
        auth_(WithoutFleetKey(options_.security)) {
    if (auto it = options_.security.keys.find(kLcmFleetKeyId);
        it != options_.security.keys.end())
      fleet_key_ = it->second;
    if (!lcm_.good())
      throw std::runtime_error(
          "--lcm " + options_.url +
          ": cannot create the LCM provider (for udpm on loopback: ip link "
          "set lo multicast on; ip route add 224.0.0.0/4 dev lo)");
    if (options_.max_strokes_per_job < 1)
      throw std::invalid_argument("max_strokes_per_job must be >= 1");
    publisher_ = std::make_shared<LcmPublisher>(&lcm_);
    lcm_.subscribe(kLcmQueryChannel, &LcmEndpointImpl::OnQueryBytes, this);
    lcm_.subscribe(kLcmStrokeChannel, &LcmEndpointImpl::OnChunkBytes, this);
    lcm_.subscribe(
        kLcmSignedStrokeChannel, &LcmEndpointImpl::OnSignedChunkBytes, this);
    // The drop counters exist (at 0) from the start.
    for (LcmDropReason r : {LcmDropReason::kForged,
                            LcmDropReason::kReplayed,
                            LcmDropReason::kStale,
                            LcmDropReason::kUnknownRobot,
                            LcmDropReason::kUnsigned,
                            LcmDropReason::kMalformed,
                            LcmDropReason::kTruncated,
                            LcmDropReason::kWrongHash,
                            LcmDropReason::kOversized,
                            LcmDropReason::kInternal})
      Count(DropCounter(r), 0);
    Count("lcm_signed_accepted_total", 0);
    // Tell the fleet about every new model version, from any endpoint.
    std::weak_ptr<LcmPublisher> weak = publisher_;
    library_.AddModelListener([weak,
                               keys = BroadcastKeys(),
                               send_unsigned = options_.security.send_unsigned](
                                  const CachedModel& m) {
      auto p = weak.lock();
      if (!p) return;
      model_update_v1 u;
      u.utime = NowUtime();
      u.job_id = tl_ingesting_job;
      // Why the version was made ("upload", "diagnosis", ...), as stored.
      const json doc = json::parse(m.json_text, nullptr, false);
      u.reason =
          doc.is_object() && doc.contains("reason") && doc["reason"].is_string()
              ? doc["reason"].get<std::string>()
              : std::string();
      u.model = ToLcm(m);
      p->PublishToRobots(kLcmModelUpdateChannel, u, keys, send_unsigned);
    });
  }

  ~LcmEndpointImpl() {
    Stop();
    publisher_->Close();
  }

  void Start() {
    if (thread_.joinable()) return;
    stop_ = false;
    thread_ = std::thread([this] { Run(); });
  }

  void Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }

  void HandleMessage(const std::string& channel,
                     const void* data,
                     std::size_t size) {
    lcm::ReceiveBuffer rbuf{};
    rbuf.data = const_cast<void*>(data);
    rbuf.data_size =
        static_cast<std::uint32_t>(std::min<std::size_t>(size, UINT32_MAX));
    if (channel == kLcmQueryChannel) OnQueryBytes(&rbuf, channel);
    if (channel == kLcmStrokeChannel) OnChunkBytes(&rbuf, channel);
    if (channel == kLcmSignedStrokeChannel) OnSignedChunkBytes(&rbuf, channel);
    try {
      for (const ReassemblyEvent& e : reassembler_.Poll(NowMonotonicS()))
        OnReassemblyEvent(e);
      while (lcm_.handleTimeout(0) > 0) {
      }
    } catch (const std::exception& e) {
      std::cerr << "frictiond: lcm endpoint: " << e.what() << "\n";
    }
  }

 private:
  // Per-job state of this process (the job itself lives in the Store).
  struct JobProgress {
    std::vector<StrokeData> strokes;  // complete strokes not yet ingested
    std::vector<double> slip_fn_n, slip_v_mm_s;
    std::set<int> done_strokes;  // reassembled (duplicates are ignored)
  };

  void Run() {
    while (!stop_) {
      try {
        const int r = lcm_.handleTimeout(options_.poll_ms);
        if (r < 0) {
          std::cerr << "frictiond: lcm handleTimeout failed\n";
          std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
        for (const ReassemblyEvent& e : reassembler_.Poll(NowMonotonicS()))
          OnReassemblyEvent(e);
      } catch (const std::exception& e) {
        // Nothing may leave the thread; a handler bug must not kill LCM.
        std::cerr << "frictiond: lcm endpoint: " << e.what() << "\n";
      }
    }
  }

  using SigningKeys = std::vector<std::pair<std::string, std::string>>;
  // The security options without the fleet key (the keys entry "fleet"
  // signs messages to robots; it never authenticates a robot's write).
  static LcmSecurityOptions WithoutFleetKey(LcmSecurityOptions s) {
    s.keys.erase(kLcmFleetKeyId);
    return s;
  }
  // Keys of a message every robot may read (model updates): each robot's
  // key (at most kMaxBroadcastKeys) and the fleet key.
  SigningKeys BroadcastKeys() const {
    constexpr std::size_t kMaxBroadcastKeys = 64;
    SigningKeys keys;
    for (const auto& [robot, key] : auth_.options().keys) {
      if (keys.size() >= kMaxBroadcastKeys) break;
      keys.emplace_back(robot, key);
    }
    if (!fleet_key_.empty()) keys.emplace_back(kLcmFleetKeyId, fleet_key_);
    return keys;
  }
  // Keys of a message to `robot`: its own key when it has one, else as a
  // broadcast.
  SigningKeys KeysFor(const std::string& robot) const {
    if (const std::string* key = auth_.KeyOf(robot)) return {{robot, *key}};
    return BroadcastKeys();
  }
  template <class Message>
  void PublishToRobot(const char* channel,
                      const Message& m,
                      const std::string& robot) {
    publisher_->PublishToRobots(
        channel, m, KeysFor(robot), options_.security.send_unsigned);
  }
  // material_reply_v1, and beside it material_reply_v2 with what the
  // recogniser made of the query's image (null: no image).
  void PublishReply(const material_reply_v1& reply,
                    const LcmRecognition* recognition = nullptr) {
    PublishToRobot(kLcmReplyChannel, reply, reply.robot);
    PublishToRobot(kLcmReplyV2Channel,
                   MakeMaterialReplyV2(reply, recognition),
                   reply.robot);
  }

  void PublishError(const std::string& type,
                    const std::string& request_id,
                    const std::string& robot,
                    std::int64_t job_id,
                    int stroke,
                    int seq,
                    const std::string& field,
                    const std::string& reason) {
    error_v1 e;
    e.utime = NowUtime();
    e.message_type = type;
    e.request_id = request_id.substr(0, kMaxTextField);
    e.robot = robot.substr(0, kMaxTextField);
    e.job_id = job_id;
    e.stroke = stroke;
    e.seq = seq;
    e.field = field;
    e.reason = reason;
    publisher_->Publish(kLcmErrorChannel, e);
  }

  // --- queries --------------------------------------------------------------
  // liblcm's callbacks: no exception may cross into liblcm (its C frames
  // cannot unwind, and an exception there left it in a state that aborted
  // the daemon on the next message). Every failure is counted as
  // reason="internal" and answered; the endpoint keeps serving.
  template <class Handler>
  void Guarded(const char* type,
               const lcm::ReceiveBuffer* rbuf,
               Handler handler) noexcept {
    try {
      try {
        handler(static_cast<const std::uint8_t*>(rbuf->data),
                static_cast<std::size_t>(rbuf->data_size));
      } catch (const std::exception& e) {
        Count(DropCounter(LcmDropReason::kInternal));
        std::cerr << "frictiond: lcm " << type << ": " << e.what() << "\n";
        PublishError(type,
                     "",
                     "",
                     0,
                     0,
                     -1,
                     "(daemon)",
                     std::string(type) +
                         " not handled (internal error, nothing stored; send "
                         "it again later): " +
                         e.what());
      } catch (...) {
        Count(DropCounter(LcmDropReason::kInternal));
        PublishError(type,
                     "",
                     "",
                     0,
                     0,
                     -1,
                     "(daemon)",
                     std::string(type) + " not handled (internal error)");
      }
    } catch (...) {
      // Even the error report failed (e.g. out of memory): nothing more to do.
    }
  }
  void OnQueryBytes(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    Guarded("material_query_v1",
            rbuf,
            [this](const std::uint8_t* data, std::size_t size) {
              HandleQueryBytes(data, size);
            });
  }
  void OnChunkBytes(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    Guarded("stroke_chunk_v1",
            rbuf,
            [this](const std::uint8_t* data, std::size_t size) {
              HandleChunkBytes(data, size);
            });
  }
  void OnSignedChunkBytes(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    Guarded("stroke_chunk_v2",
            rbuf,
            [this](const std::uint8_t* data, std::size_t size) {
              HandleSignedChunkBytes(data, size);
            });
  }

  static LcmDropReason DropReasonOf(LcmDecodeFailure f) {
    switch (f) {
      case LcmDecodeFailure::kTruncated:
        return LcmDropReason::kTruncated;
      case LcmDecodeFailure::kWrongHash:
        return LcmDropReason::kWrongHash;
      case LcmDecodeFailure::kOversized:
        return LcmDropReason::kOversized;
      default:
        return LcmDropReason::kMalformed;
    }
  }

  // A message that does not decode: counted by reason and answered with an
  // error_v1 naming the field, with the sender's ids as far as they were
  // decoded before the failure.
  void DropUndecodable(const char* type,
                       const LcmDecodeResult& r,
                       std::size_t size,
                       const std::string& request_id,
                       const std::string& robot,
                       std::int64_t job_id,
                       int stroke,
                       int seq) {
    Count(DropCounter(DropReasonOf(r.failure)));
    PublishError(type,
                 request_id,
                 robot,
                 job_id,
                 stroke,
                 seq,
                 r.field,
                 std::string(type) + " dropped (" +
                     LcmDecodeFailureName(r.failure) + ", " +
                     std::to_string(size) + " bytes): " + r.detail);
  }

  void HandleQueryBytes(const std::uint8_t* data, std::size_t size) {
    material_query_v1 q;
    if (const LcmDecodeResult r = DecodeLcm(data, size, &q, decode_limits_);
        !r.ok()) {
      DropUndecodable(
          "material_query_v1", r, size, q.request_id, q.robot, 0, 0, -1);
      // The robot waits for a reply to its request: answer it when known.
      if (!q.request_id.empty()) {
        material_reply_v1 reply;
        reply.utime = NowUtime();
        reply.request_id = q.request_id.substr(0, kMaxTextField);
        reply.robot = q.robot.substr(0, kMaxTextField);
        reply.status = material_reply_v1::STATUS_ERROR;
        reply.reason = "material_query_v1 dropped (" +
                       std::string(LcmDecodeFailureName(r.failure)) +
                       "): " + r.detail;
        reply.job_id = 0;
        reply.recognition_score = 0;
        reply.model.version = 0;
        reply.model.n_terms = reply.model.n_quantiles = 0;
        reply.model.has_lugre = false;
        PublishReply(reply);
      }
      return;
    }
    OnQuery(std::move(q));
  }

  void OnQuery(material_query_v1 q) {
    material_reply_v1 reply;
    reply.utime = NowUtime();
    reply.request_id = q.request_id.substr(0, kMaxTextField);
    reply.robot = q.robot.substr(0, kMaxTextField);
    reply.material = q.material;
    reply.fingertip = q.fingertip.empty() ? "default" : q.fingertip;
    reply.job_id = 0;
    reply.recognition_score = 0;
    reply.model.n_terms = 0;
    reply.model.n_quantiles = 0;
    reply.model.has_lugre = false;
    std::optional<LcmRecognition> seen;  // the image's recognition
    auto reject = [&](const std::string& field, const std::string& why) {
      reply.status = material_reply_v1::STATUS_ERROR;
      reply.reason = why;
      PublishReply(reply, seen ? &*seen : nullptr);
      PublishError(
          "material_query_v1", q.request_id, q.robot, 0, 0, -1, field, why);
    };
    if (q.request_id.size() > kMaxTextField)
      return reject("request_id",
                    "request_id: " + std::to_string(q.request_id.size()) +
                        " characters (at most 128)");
    if (q.robot.size() > kMaxTextField)
      return reject("robot",
                    "robot: " + std::to_string(q.robot.size()) +
                        " characters (at most 128)");
    if (q.image_size > 0) {
      // The recognition hook (paper 000 Fig. 11: material recognition);
      // below its confidence threshold the material is unknown and the
      // query's material id names the new material.
      if (!options_.recognize)
        return reject("image",
                      "image: this frictiond has no recognition (built "
                      "without OpenCV); query by material id");
      ImageRecognition r;
      try {
        r = options_.recognize(std::string(q.image.begin(), q.image.end()));
      } catch (const std::invalid_argument& e) {
        return reject("image", std::string("image: ") + e.what());
      }
      seen =
          LcmRecognition{r.unknown, r.reason, r.operating_point, r.candidates};
      if (!r.unknown && !r.candidates.empty()) {
        q.material = r.candidates.front().first;
        reply.material = q.material;
        reply.recognition_score = r.candidates.front().second;
      } else if (q.material.empty()) {
        return reject("material",
                      "material: empty, and the image was not recognised "
                      "(unknown material); give the id the new material "
                      "should get to start its identification");
      }
    }
    try {
      auto model =
          library_.RequireModel(q.material, reply.fingertip, "lcm:" + q.robot);
      reply.status = material_reply_v1::STATUS_KNOWN;
      reply.model = ToLcm(*model);
      PublishReply(reply, seen ? &*seen : nullptr);
    } catch (const RequestError& e) {
      if (e.status() != 404 || !e.extra().contains("identification"))
        return reject(e.field() == "id" ? "material" : e.field(), e.what());
      const json& ident = e.extra()["identification"];
      reply.status = material_reply_v1::STATUS_UNKNOWN;
      reply.reason = e.what();
      reply.job_id = ident.value("job_id", std::int64_t{0});
      PublishReply(reply, seen ? &*seen : nullptr);
      PublishIdentificationRequest(reply.job_id,
                                   q.request_id,
                                   q.robot,
                                   q.material,
                                   reply.fingertip,
                                   ident.at("stroke"),
                                   /*stroke=*/0,
                                   std::nullopt);
    } catch (const std::exception& e) {
      // The store or library failed (e.g. PostgreSQL away): the robot gets
      // an error reply, the endpoint keeps serving.
      Count(DropCounter(LcmDropReason::kInternal));
      return reject("(daemon)",
                    std::string("the library is unavailable (nothing "
                                "stored; ask again later): ") +
                        e.what());
    }
  }

  // Sends the stroke plan; `missing` narrows it to a follow-up region.
  void PublishIdentificationRequest(std::int64_t job_id,
                                    const std::string& request_id,
                                    const std::string& robot,
                                    const std::string& material,
                                    const std::string& fingertip,
                                    const json& plan,
                                    int stroke,
                                    const std::optional<SpanRect>& missing) {
    identification_request_v1 r;
    r.utime = NowUtime();
    r.job_id = job_id;
    r.stroke = stroke;
    r.request_id = request_id.substr(0, kMaxTextField);
    r.robot = robot.substr(0, kMaxTextField);
    r.material = material;
    r.fingertip = fingertip;
    const SpanRect span = missing ? *missing : PlanSpan(plan);
    r.fn_min_n = span.fn_min_n;
    r.fn_max_n = span.fn_max_n;
    r.v_min_mm_s = span.v_min_mm_s;
    r.v_max_mm_s = span.v_max_mm_s;
    r.max_duration_s = plan.value("max_duration_s", 120.0);
    r.min_span_pct = plan.value("min_span_pct", 50.0);
    r.follow_up = missing.has_value();
    r.instructions =
        std::string(missing ? "follow-up: the strokes so far covered too "
                              "little of the Fn-v span; "
                            : "") +
        "slide the fingertip in repeated strokes with rests between them, "
        "sweeping normal force over [fn_min_n, fn_max_n] and peak speed over "
        "[v_min_mm_s, v_max_mm_s]; stream the samples as stroke_chunk_v1 on " +
        kLcmStrokeChannel + " with job_id " + std::to_string(job_id) +
        " and stroke " + std::to_string(stroke);
    PublishToRobot(kLcmIdentRequestChannel, r, r.robot);
    // v2: the same plus the LuGre pair (a plan stored before the pair
    // existed asks for none).
    identification_request_v2 r2;
    r2.utime = r.utime;
    r2.job_id = r.job_id;
    r2.stroke = r.stroke;
    r2.request_id = r.request_id;
    r2.robot = r.robot;
    r2.material = r.material;
    r2.fingertip = r.fingertip;
    r2.fn_min_n = r.fn_min_n;
    r2.fn_max_n = r.fn_max_n;
    r2.v_min_mm_s = r.v_min_mm_s;
    r2.v_max_mm_s = r.v_max_mm_s;
    r2.max_duration_s = r.max_duration_s;
    r2.min_span_pct = r.min_span_pct;
    r2.follow_up = r.follow_up;
    r2.instructions = r.instructions;
    const json* lugre = plan.contains("lugre") && plan["lugre"].is_object()
                            ? &plan["lugre"]
                            : nullptr;
    r2.lugre_pair = lugre != nullptr;
    const double nan = std::nan("");
    auto num = [&](const char* group, const char* key) {
      if (!lugre) return nan;
      const json& g = group ? lugre->value(group, json::object()) : *lugre;
      return g.value(key, nan);
    };
    r2.lugre_fn_n = num(nullptr, "fn_n");
    r2.lugre_slow_accel_mm_s2 = num("slow", "accel_mm_s2");
    r2.lugre_slow_peak_mm_s = num("slow", "peak_mm_s");
    r2.lugre_fast_strokes =
        lugre ? lugre->value("fast", json::object()).value("strokes", 0) : 0;
    r2.lugre_fast_accel_mm_s2 = num("fast", "accel_mm_s2");
    r2.lugre_fast_peak_mm_s = num("fast", "peak_mm_s");
    r2.lugre_rest_s = num(nullptr, "rest_s");
    if (lugre)
      r2.instructions +=
          "; then, at normal force lugre_fn_n, the LuGre pair: a slow "
          "triangle to lugre_slow_peak_mm_s at lugre_slow_accel_mm_s2 and "
          "lugre_fast_strokes fast triangles to lugre_fast_peak_mm_s at "
          "lugre_fast_accel_mm_s2, lugre_rest_s apart, in the same stroke";
    PublishToRobot(kLcmIdentRequestV2Channel, r2, r2.robot);
  }

  static SpanRect PlanSpan(const json& plan) {
    SpanRect s;
    s.fn_min_n = plan.at("fn_n").at(0).get<double>();
    s.fn_max_n = plan.at("fn_n").at(1).get<double>();
    s.v_min_mm_s = plan.at("v_mm_s").at(0).get<double>();
    s.v_max_mm_s = plan.at("v_mm_s").at(1).get<double>();
    return s;
  }

  // --- stroke chunks
  // ----------------------------------------------------------
  static std::string DropCounter(LcmDropReason r) {
    return std::string("lcm_dropped_total{reason=\"") + LcmDropReasonName(r) +
           "\"}";
  }
  void Count(const std::string& counter, std::int64_t by = 1) {
    if (options_.metrics) options_.metrics->Increment(counter, by);
  }
  // A write that fails the security checks: counted, answered with an
  // error_v1 naming the field (except a replay), nothing of it kept.
  void Drop(const char* type,
            LcmDropReason reason,
            const std::string& robot,
            std::int64_t job_id,
            int stroke,
            int seq,
            const std::string& field,
            const std::string& detail) {
    Count(DropCounter(reason));
    // A replay is not answered: the original got through, and a network
    // duplicate is no error of the sender's.
    if (reason == LcmDropReason::kReplayed) return;
    PublishError(type,
                 "",
                 robot,
                 job_id,
                 stroke,
                 seq,
                 field,
                 std::string(type) + " dropped (" + LcmDropReasonName(reason) +
                     "): " + detail);
  }

  // Unsigned chunks: only when the daemon allows them.
  void HandleChunkBytes(const std::uint8_t* data, std::size_t size) {
    stroke_chunk_v1 m;
    if (const LcmDecodeResult r = DecodeLcm(data, size, &m, decode_limits_);
        !r.ok())
      return DropUndecodable("stroke_chunk_v1",
                             r,
                             size,
                             "",
                             m.robot,
                             m.job_id,
                             m.stroke,
                             r.field == "seq" ? -1 : m.seq);
    if (!options_.security.allow_unsigned)
      return Drop("stroke_chunk_v1",
                  LcmDropReason::kUnsigned,
                  m.robot.substr(0, kMaxTextField),
                  m.job_id,
                  m.stroke,
                  m.seq,
                  "(unsigned)",
                  "this daemon accepts only signed stroke chunks "
                  "(stroke_chunk_v2 on " +
                      std::string(kLcmSignedStrokeChannel) +
                      "; or run it with lcm_allow_unsigned)");
    HandleChunk(std::move(m), "stroke_chunk_v1");
  }

  // Signed chunks: robot key, MAC, timestamp and nonce, then as unsigned.
  void HandleSignedChunkBytes(const std::uint8_t* data, std::size_t size) {
    stroke_chunk_v2 s;
    if (const LcmDecodeResult r = DecodeLcm(data, size, &s, decode_limits_);
        !r.ok())
      // Not verified: the ids it names may be anyone's.
      return DropUndecodable("stroke_chunk_v2",
                             r,
                             size,
                             "",
                             s.robot,
                             s.job_id,
                             s.stroke,
                             r.field == "seq" ? -1 : s.seq);
    const LcmAuthVerdict v = auth_.Check(
        s.robot,
        s.utime,
        LcmMessageNonce(s),
        LcmMessageMac(s),
        [&s](const std::string& key) { return CalcLcmMessageMac(s, key); },
        NowUtime());
    if (!v.ok())
      return Drop("stroke_chunk_v2",
                  v.reason,
                  s.robot.substr(0, kMaxTextField),
                  s.job_id,
                  s.stroke,
                  s.seq,
                  v.field,
                  v.detail);
    Count("lcm_signed_accepted_total");
    stroke_chunk_v1 m;
    m.utime = s.utime;
    m.job_id = s.job_id;
    m.stroke = s.stroke;
    m.robot = std::move(s.robot);
    m.material = std::move(s.material);
    m.fingertip = std::move(s.fingertip);
    m.seq = s.seq;
    m.total_chunks = s.total_chunks;
    m.last = s.last;
    m.n_samples = s.n_samples;
    m.t_s = std::move(s.t_s);
    m.fn_n = std::move(s.fn_n);
    m.ft_n = std::move(s.ft_n);
    m.v_mm_s = std::move(s.v_mm_s);
    HandleChunk(std::move(m), "stroke_chunk_v2");
  }

  // A chunk whose sender is trusted: validation and reassembly.
  void HandleChunk(stroke_chunk_v1 m, const char* type) {
    auto reject = [&](const std::string& field, const std::string& why) {
      PublishError(type, "", m.robot, m.job_id, m.stroke, m.seq, field, why);
    };
    const std::string fingertip = m.fingertip.empty() ? "default" : m.fingertip;
    if (m.robot.size() > kMaxTextField)
      return reject("robot",
                    "robot: " + std::to_string(m.robot.size()) +
                        " characters (at most 128)");
    // The job must exist, be open and belong to the named pair.
    std::optional<IdentificationJob> job;
    if (m.job_id > 0) job = library_.store().GetJob(m.job_id);
    if (!job)
      return reject("job_id",
                    "job_id = " + std::to_string(m.job_id) +
                        " (no such identification job; query the "
                        "material first)");
    if (job->state == "fitted" || job->state == "failed")
      return reject("job_id",
                    "job_id = " + std::to_string(m.job_id) + " (the job is " +
                        job->state + "; query the material again)");
    if (m.material != job->material)
      return reject("material",
                    "material = '" + m.material.substr(0, 64) + "' (job " +
                        std::to_string(job->id) + " is for '" + job->material +
                        "')");
    if (fingertip != job->fingertip)
      return reject("fingertip",
                    "fingertip = '" + fingertip.substr(0, 64) + "' (job " +
                        std::to_string(job->id) + " is for '" + job->fingertip +
                        "')");
    // In a fleet every daemon hears the chunks; the one that claims the job
    // (once, in the shared store) acts on it, the others stay silent.
    // The claim is a lease, renewed while chunks arrive, so that the job of
    // a daemon that died is taken over (Store::ClaimJob).
    const double now_s = NowMonotonicS();
    auto claim = claimed_.find(job->id);
    if (claim == claimed_.end() || now_s - claim->second > kClaimRenewS) {
      if (!library_.store().ClaimJob(job->id, worker_id_)) {
        if (claim != claimed_.end()) claimed_.erase(claim);
        return;
      }
      claimed_[job->id] = now_s;
    }
    JobProgress& jp = ProgressOf(*job);
    if (jp.done_strokes.count(m.stroke)) return;  // late duplicate
    if (m.stroke >= options_.max_strokes_per_job)
      return reject("stroke",
                    "stroke = " + std::to_string(m.stroke) + " (at most " +
                        std::to_string(options_.max_strokes_per_job) +
                        " strokes per job)");
    StrokeChunk c;
    c.job_id = m.job_id;
    c.stroke = m.stroke;
    c.seq = m.seq;
    c.total_chunks = m.total_chunks;
    c.last = m.last;
    c.t_s = std::move(m.t_s);
    c.fn_n = std::move(m.fn_n);
    c.ft_n = std::move(m.ft_n);
    c.v_mm_s = std::move(m.v_mm_s);
    ChunkOutcome outcome;
    try {
      outcome = reassembler_.Add(c, NowMonotonicS());
    } catch (const std::invalid_argument& e) {
      return reject(FieldOf(e.what()), e.what());
    }
    if (outcome == ChunkOutcome::kDuplicate) return;
    if (job->state == "requested") {
      library_.store().UpdateJob(job->id,
                                 "stroking",
                                 "receiving stroke " +
                                     std::to_string(m.stroke) + " from " +
                                     (m.robot.empty() ? "a robot" : m.robot));
      job->state = "stroking";
    }
    const StrokeKey key{c.job_id, c.stroke};
    if (outcome == ChunkOutcome::kAccepted) {
      if (auto p = reassembler_.Progress(key))
        PublishProgress(*job,
                        m.robot,
                        *p,
                        "stroking",
                        -1,
                        0,
                        "chunk " + std::to_string(c.seq) + " received",
                        /*with_missing=*/false);
      return;
    }
    OnStrokeComplete(*job, m.robot, key, type);
  }

  void PublishProgress(const IdentificationJob& job,
                       const std::string& robot,
                       const StrokeProgress& p,
                       const std::string& state,
                       double span_pct,
                       int version,
                       const std::string& detail,
                       bool with_missing) {
    coverage_progress_v1 out;
    out.utime = NowUtime();
    out.job_id = job.id;
    out.stroke = p.key.stroke;
    out.material = job.material;
    out.fingertip = job.fingertip;
    out.robot = robot.substr(0, kMaxTextField);
    out.state = state;
    out.chunks_received = p.chunks_received;
    out.chunks_expected = p.chunks_expected;
    if (with_missing) out.missing_seqs = p.missing;
    out.n_missing = static_cast<int32_t>(out.missing_seqs.size());
    out.samples = static_cast<int64_t>(p.samples);
    out.span_pct = span_pct;
    out.min_span_pct = library_.options().plan.min_span_pct;
    out.model_version = version;
    out.detail = detail;
    PublishToRobot(kLcmProgressChannel, out, out.robot);
  }

  void OnReassemblyEvent(const ReassemblyEvent& e) {
    auto job = library_.store().GetJob(e.progress.key.job_id);
    if (!job) return;
    if (e.kind == ReassemblyEvent::Kind::kResend) {
      PublishProgress(*job,
                      "",
                      e.progress,
                      job->state,
                      -1,
                      0,
                      "resend: " + e.reason,
                      /*with_missing=*/true);
      return;
    }
    PublishError("stroke_chunk_v1",
                 "",
                 "",
                 job->id,
                 e.progress.key.stroke,
                 -1,
                 "seq",
                 e.reason);
    PublishProgress(*job,
                    "",
                    e.progress,
                    job->state,
                    -1,
                    0,
                    e.reason,
                    /*with_missing=*/true);
  }

  // Adds a complete stroke to the job's progress, with its slipping (Fn, v)
  // samples for the span coverage (paper 000 III-E), labelled as the fit
  // will label them (the pair's labelling, else the defaults).
  void AddStroke(const IdentificationJob& job,
                 StrokeData stroke,
                 JobProgress* jp) {
    SlipLabelOptions labelling;
    if (auto prev = library_.FindModel(job.material, job.fingertip);
        prev && prev->set.stochastic)
      labelling = prev->set.stochastic->labelling;
    StrokeData labelled = stroke;
    EnsureLabels(&labelled, labelling);
    const std::vector<bool> mask = CalcFitMask(labelled, labelling);
    for (std::size_t i = 0; i < labelled.size(); ++i) {
      if (!mask[i]) continue;
      jp->slip_fn_n.push_back(labelled.fn_n[i]);
      jp->slip_v_mm_s.push_back(labelled.v_mm_s[i]);
    }
    jp->strokes.push_back(std::move(stroke));
  }

  // The job's progress; on first use in this process it starts from the
  // strokes the store keeps for the job (after a restart, or for a job taken
  // over from a daemon that died).
  JobProgress& ProgressOf(const IdentificationJob& job) {
    if (auto it = jobs_.find(job.id); it != jobs_.end()) return it->second;
    const auto kept = library_.store().ListJobStrokes(job.id);
    JobProgress& jp = jobs_[job.id];
    for (const auto& [index, csv] : kept) {
      try {
        AddStroke(job, ParseStrokeCsv(csv), &jp);
        jp.done_strokes.insert(index);
      } catch (const std::exception& e) {
        std::cerr << "frictiond: kept stroke " << index << " of job " << job.id
                  << " unreadable, asked again: " << e.what() << "\n";
      }
    }
    return jp;
  }

  // Forgets a closed job's progress and its kept strokes.
  void CloseJob(std::int64_t job_id) {
    jobs_.erase(job_id);
    try {
      library_.store().DeleteJobStrokes(job_id);
    } catch (const std::exception& e) {
      std::cerr << "frictiond: kept strokes of job " << job_id
                << " not deleted: " << e.what() << "\n";
    }
  }

  // Audit log entry for a write that came over LCM: actor "lcm:<robot>",
  // role "robot" for signed chunks ("" for unsigned ones), the job's pair,
  // and `detail` (status, version or why). A store that is down loses the
  // entry, not the answer to the robot.
  void AuditLcmWrite(const IdentificationJob& job,
                     const std::string& robot,
                     const char* type,
                     json detail) {
    const bool is_signed = std::string(type) == "stroke_chunk_v2";
    AuditEntry e;
    e.actor = ("lcm:" + robot).substr(0, 128);
    e.role = is_signed ? "robot" : "";
    e.action = std::string("LCM ") + type;
    e.material = job.material;
    detail["job"] = job.id;
    detail["fingertip"] = job.fingertip;
    detail["signed"] = is_signed;
    e.detail = detail.dump();
    try {
      library_.store().AppendAudit(e);
    } catch (const std::exception& ex) {
      std::cerr << "frictiond: audit of an LCM write lost: " << ex.what()
                << "\n";
    }
  }

  void OnStrokeComplete(IdentificationJob job,
                        const std::string& robot,
                        const StrokeKey& key,
                        const char* type) {
    const StrokeProgress progress = *reassembler_.Progress(key);
    JobProgress& jp = ProgressOf(job);
    const json plan = json::parse(job.plan_json);
    StrokeData stroke;
    try {
      stroke = reassembler_.Take(key);
      const double duration_s = stroke.t_s.back() - stroke.t_s.front();
      const double max_s = plan.value("max_duration_s", 120.0);
      if (!(duration_s <= max_s))
        throw std::invalid_argument(
            "t_s: the stroke lasts " + std::to_string(duration_s) +
            " s (the plan allows max_duration_s = " + std::to_string(max_s) +
            " s)");
    } catch (const std::invalid_argument& e) {
      PublishError("stroke_chunk_v1",
                   "",
                   robot,
                   job.id,
                   key.stroke,
                   -1,
                   FieldOf(e.what()),
                   e.what());
      PublishProgress(job,
                      robot,
                      progress,
                      job.state,
                      -1,
                      0,
                      std::string("stroke rejected: ") + e.what(),
                      false);
      return;
    }
    // Kept in the store until the job closes: a restart (or a daemon taking
    // the job over) continues with it instead of asking for it again.
    try {
      library_.store().PutJobStroke(
          job.id, key.stroke, FormatStrokeCsv(stroke));
    } catch (const std::exception& e) {
      const std::string why =
          std::string("the stroke could not be kept (store: ") + e.what() +
          "); send it again";
      PublishError(type, "", robot, job.id, key.stroke, -1, "store", why);
      PublishProgress(job, robot, progress, job.state, -1, 0, why, false);
      return;
    }
    jp.done_strokes.insert(key.stroke);
    AddStroke(job, std::move(stroke), &jp);
    const SpanRect plan_span = PlanSpan(plan);
    const SpanCoverage cov =
        CalcSpanCoverage(jp.slip_fn_n, jp.slip_v_mm_s, plan_span);
    const double min_pct = plan.value("min_span_pct", 50.0);
    char span_text[160];
    std::snprintf(span_text,
                  sizeof span_text,
                  "span %.1f %% of the plan (needs %.1f %%) from %d slipping "
                  "samples in %zu stroke(s)",
                  cov.span_pct,
                  min_pct,
                  cov.samples,
                  jp.strokes.size());
    if (cov.span_pct < min_pct) {
      if (static_cast<int>(jp.strokes.size()) >= options_.max_strokes_per_job) {
        const std::string why = std::string("too little span coverage: ") +
                                span_text + " after the maximum of " +
                                std::to_string(options_.max_strokes_per_job) +
                                " strokes";
        library_.store().UpdateJob(job.id, "failed", why);
        AuditLcmWrite(job, robot, type, {{"status", 422}, {"why", why}});
        CloseJob(job.id);  // before the robot hears of it
        PublishProgress(
            job, robot, progress, "failed", cov.span_pct, 0, why, false);
        return;
      }
      // A follow-up stroke for the missing region instead of a weak model.
      char region[200];
      std::snprintf(region,
                    sizeof region,
                    "; follow-up stroke %d asked for fn_n %.2f-%.2f N, "
                    "v_mm_s %.1f-%.1f mm/s",
                    key.stroke + 1,
                    cov.missing.fn_min_n,
                    cov.missing.fn_max_n,
                    cov.missing.v_min_mm_s,
                    cov.missing.v_max_mm_s);
      const std::string detail = span_text + std::string(region);
      library_.store().UpdateJob(job.id, "stroking", detail);
      PublishProgress(
          job, robot, progress, "stroking", cov.span_pct, 0, detail, false);
      PublishIdentificationRequest(job.id,
                                   "",
                                   robot,
                                   job.material,
                                   job.fingertip,
                                   plan,
                                   key.stroke + 1,
                                   cov.missing);
      return;
    }
    library_.store().UpdateJob(job.id, "enough_coverage", span_text);
    PublishProgress(job,
                    robot,
                    progress,
                    "enough_coverage",
                    cov.span_pct,
                    0,
                    span_text,
                    false);
    // One upload of all the job's strokes: later strokes are shifted to
    // start 1 s after the previous one ended (a gap = an unrecorded rest).
    StrokeData all;
    for (const StrokeData& s : jp.strokes) {
      StrokeData shifted = s;
      if (!all.empty()) {
        const double shift = all.t_s.back() + 1.0 - s.t_s.front();
        for (double& t : shifted.t_s) t += shift;
      }
      all.Append(shifted);
    }
    IngestOptions io;
    io.fingertip = job.fingertip;
    io.robot = ("lcm:" + robot).substr(0, 128);
    struct IngestingJob {  // the model listener reads it on this thread
      explicit IngestingJob(std::int64_t id) { tl_ingesting_job = id; }
      ~IngestingJob() { tl_ingesting_job = 0; }
    };
    try {
      const IngestingJob ingesting(job.id);
      const IngestResult r =
          library_.IngestStrokes(job.material, FormatStrokeCsv(all), io);
      const std::string detail =
          "fitted version " + std::to_string(r.version) + " (" + r.fit_status +
          (r.fit_note.empty() ? "" : ": " + r.fit_note) + "); " + span_text;
      library_.store().UpdateJob(job.id, "fitted", detail);
      AuditLcmWrite(job,
                    robot,
                    type,
                    {{"status", 201},
                     {"version", r.version},
                     {"strokes", jp.strokes.size()}});
      CloseJob(job.id);  // before the robot hears of it
      PublishProgress(job,
                      robot,
                      progress,
                      "fitted",
                      cov.span_pct,
                      r.version,
                      detail,
                      false);
    } catch (const RequestError& e) {
      const std::string why = std::string("identification failed: ") + e.what();
      library_.store().UpdateJob(job.id, "failed", why);
      AuditLcmWrite(
          job,
          robot,
          type,
          {{"status", e.status()}, {"field", e.field()}, {"why", why}});
      CloseJob(job.id);
      PublishError("stroke_chunk_v1",
                   "",
                   robot,
                   job.id,
                   key.stroke,
                   -1,
                   e.field(),
                   e.what());
      PublishProgress(
          job, robot, progress, "failed", cov.span_pct, 0, why, false);
    }
  }

  FrictionLibrary& library_;
  LcmEndpointOptions options_;
  lcm::LCM lcm_;
  std::shared_ptr<LcmPublisher> publisher_;
  StrokeReassembler reassembler_;
  LcmAuthenticator auth_;
  std::string fleet_key_;  // raw; empty: none
  LcmDecodeLimits decode_limits_;
  std::map<std::int64_t, JobProgress> jobs_;
  // Jobs this endpoint claimed, with the time of the last claim renewal.
  std::map<std::int64_t, double> claimed_;
  const std::string worker_id_ =
      options_.worker_id.empty() ? MakeWorkerId() : options_.worker_id;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace internal

LcmEndpoint::LcmEndpoint(FrictionLibrary& library, LcmEndpointOptions options)
    : impl_(std::make_unique<internal::LcmEndpointImpl>(library,
                                                        std::move(options))) {}
LcmEndpoint::~LcmEndpoint() = default;
void LcmEndpoint::Start() { impl_->Start(); }
void LcmEndpoint::Stop() { impl_->Stop(); }
void LcmEndpoint::HandleMessage(const std::string& channel,
                                const void* data,
                                std::size_t size) {
  impl_->HandleMessage(channel, data, size);
}
bool HaveLcmEndpoint() { return true; }

}  // namespace frictiond

#else  // !FRICTIOND_HAVE_LCM

namespace frictiond {
namespace internal {
class LcmEndpointImpl {};
}  // namespace internal

LcmEndpoint::LcmEndpoint(FrictionLibrary&, LcmEndpointOptions options) {
  throw std::invalid_argument("--lcm " + options.url +
                              ": this build has no LCM support "
                              "(FRICTIOND_WITH_LCM=OFF)");
}
LcmEndpoint::~LcmEndpoint() = default;
void LcmEndpoint::Start() {}
void LcmEndpoint::Stop() {}
void LcmEndpoint::HandleMessage(const std::string&, const void*, std::size_t) {}
bool HaveLcmEndpoint() { return false; }

}  // namespace frictiond

#endif  // FRICTIOND_HAVE_LCM
