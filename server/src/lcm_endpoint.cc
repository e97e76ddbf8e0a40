// The daemon's LCM endpoint (lcm_endpoint.h, docs/lcm.md): paper 000,
// Fig. 11 (library lookup, test stroke, identification, fleet update) as a
// protocol beside HTTP, sharing FrictionLibrary.
#include "frictiond/server/lcm_endpoint.h"

#include <stdexcept>

#ifdef FRICTIOND_HAVE_LCM

#include <algorithm>
#include <atomic>
#include <chrono>
#include <iostream>
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
#include "frictiond/material_query_v1.hpp"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/model_update_v1.hpp"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lcm_codec.h"
#include "frictiond/proto/lcm_signed.h"
#include "frictiond/server/model_lookup.h"
#include "frictiond/server/request_error.h"
#include "frictiond/stroke_chunk_v1.hpp"
#include "frictiond/stroke_chunk_v2.hpp"

#include "lcm_messages.h"
#include "udp_drops.h"

namespace frictiond {

using nlohmann::json;

namespace {

constexpr std::size_t kMaxTextField = internal::kLcmMaxTextField;

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

// Job whose ingest is running on this thread, for the model listener.
thread_local std::int64_t tl_ingesting_job = 0;

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
        auth_(WithoutFleetKey(options_.security)),
        collector_(library_, CollectorOptions(options_)) {
    if (auto it = options_.security.keys.find(kLcmFleetKeyId);
        it != options_.security.keys.end())
      fleet_key_ = it->second;
    if (!lcm_.good())
      throw std::runtime_error(
          "--lcm " + options_.url +
          ": cannot create the LCM provider (for udpm on loopback: ip link "
          "set lo multicast on; ip route add 224.0.0.0/4 dev lo)");
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
                            LcmDropReason::kInternal,
                            LcmDropReason::kUnavailable,
                            LcmDropReason::kReceiveBufferFull})
      Count(DropCounter(r), 0);
    // The provider's sockets: the UDP sockets that appeared while it was
    // created and subscribed (LCM does not expose them).
    {
      std::set<std::uint64_t> opened;
      for (std::uint64_t inode : internal::SocketInodes())
        if (!sockets_before_.count(inode)) opened.insert(inode);
      lcm_sockets_ = internal::UdpSocketsAmong(opened);
      kernel_drops_ = internal::ReadUdpDrops(lcm_sockets_);
    }
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
      u.model = ModelToLcm(m);
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
  // Job claims are renewed this often while a job's chunks arrive (the
  // store lets another daemon take a claim not renewed for 60 s).
  static JobStrokeCollectorOptions CollectorOptions(
      const LcmEndpointOptions& o) {
    JobStrokeCollectorOptions c;
    c.max_strokes_per_job = o.max_strokes_per_job;
    c.claim_renew_s = 10.0;
    c.worker_id = o.worker_id.empty() ? MakeWorkerId() : o.worker_id;
    return c;
  }

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
        CountKernelDrops();
      } catch (const std::exception& e) {
        // Nothing may leave the thread; a handler bug must not kill LCM.
        std::cerr << "frictiond: lcm endpoint: " << e.what() << "\n";
      }
    }
  }

  // Adds the datagrams the kernel dropped on the provider's sockets since
  // the last look (at most once a second: it reads /proc).
  void CountKernelDrops() {
    const double now = NowMonotonicS();
    if (lcm_sockets_.empty() || now < next_drop_check_s_) return;
    next_drop_check_s_ = now + 1.0;
    const std::uint64_t drops = internal::ReadUdpDrops(lcm_sockets_);
    if (drops > kernel_drops_)
      Count(DropCounter(LcmDropReason::kReceiveBufferFull),
            static_cast<std::int64_t>(drops - kernel_drops_));
    kernel_drops_ = std::max(kernel_drops_, drops);
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
    publisher_->PublishToRobots(kLcmErrorChannel,
                                e,
                                ErrorKeysFor(e.robot),
                                options_.security.send_unsigned);
  }
  // Keys of an error_v1: the named robot's own key, else the fleet key
  // (never one copy per robot: any datagram can cause an error, and it
  // must not cost the daemon more than one signature).
  SigningKeys ErrorKeysFor(const std::string& robot) const {
    if (const std::string* key = auth_.KeyOf(robot)) return {{robot, *key}};
    if (!fleet_key_.empty()) return {{kLcmFleetKeyId, fleet_key_}};
    return {};
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
      } catch (const StoreUnavailable& e) {
        PublishUnavailable(type, "", "", 0, 0, -1, e);
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
  // The store is unavailable (e.g. PostgreSQL away): counted as
  // reason="unavailable" and answered with an error_v1 whose field is
  // "(store)"; nothing of the message was stored.
  void PublishUnavailable(const char* type,
                          const std::string& request_id,
                          const std::string& robot,
                          std::int64_t job_id,
                          int stroke,
                          int seq,
                          const StoreUnavailable& e) {
    Count(DropCounter(LcmDropReason::kUnavailable));
    std::cerr << "frictiond: lcm " << type << ": " << e.what() << "\n";
    PublishError(type,
                 request_id,
                 robot,
                 job_id,
                 stroke,
                 seq,
                 "(store)",
                 std::string(type) +
                     " not handled: the library is unavailable (nothing "
                     "stored; send it again later): " +
                     e.what());
  }
  // HandleChunk, with a store outage answered to the chunk's sender.
  void HandleChunkOrUnavailable(stroke_chunk_v1 m, const char* type) {
    const std::string robot = m.robot.substr(0, kMaxTextField);
    const std::int64_t job_id = m.job_id;
    const int stroke = m.stroke;
    const int seq = m.seq;
    try {
      HandleChunk(std::move(m), type);
    } catch (const StoreUnavailable& e) {
      PublishUnavailable(type, "", robot, job_id, stroke, seq, e);
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

  void OnQuery(const material_query_v1& q) {
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
    // The lookup (recognition, model or identification request) is the
    // service's; the endpoint answers.
    const ModelLookup found = LookUpModelForQuery(
        library_,
        options_.recognize,
        q.material,
        reply.fingertip,
        q.image_size > 0 ? std::string(q.image.begin(), q.image.end())
                         : std::string(),
        "lcm:" + q.robot);
    reply.material = found.material;
    reply.recognition_score = found.recognition_score;
    if (found.recognition) {
      const ImageRecognition& r = *found.recognition;
      seen =
          LcmRecognition{r.unknown, r.reason, r.operating_point, r.candidates};
    }
    switch (found.outcome) {
      case ModelLookup::Outcome::kKnown:
        reply.status = material_reply_v1::STATUS_KNOWN;
        reply.model = ModelToLcm(*found.model);
        PublishReply(reply, seen ? &*seen : nullptr);
        return;
      case ModelLookup::Outcome::kUnknown:
        reply.status = material_reply_v1::STATUS_UNKNOWN;
        reply.reason = found.message;
        reply.job_id = found.identification.requested
                           ? found.identification.job_id
                           : std::int64_t{0};
        PublishReply(reply, seen ? &*seen : nullptr);
        PublishIdentificationRequest(reply.job_id,
                                     q.request_id,
                                     q.robot,
                                     found.material,
                                     reply.fingertip,
                                     found.identification.plan,
                                     /*stroke=*/0,
                                     std::nullopt);
        return;
      case ModelLookup::Outcome::kRejected:
        return reject(found.field, found.message);
      case ModelLookup::Outcome::kUnavailable:
        // The store or library failed (e.g. PostgreSQL away): the robot
        // gets an error reply, the endpoint keeps serving.
        Count(DropCounter(found.store_outage ? LcmDropReason::kUnavailable
                                             : LcmDropReason::kInternal));
        return reject(found.field, found.message);
    }
  }

  // Sends the stroke plan; `missing` narrows it to a follow-up region.
  void PublishIdentificationRequest(std::int64_t job_id,
                                    const std::string& request_id,
                                    const std::string& robot,
                                    const std::string& material,
                                    const std::string& fingertip,
                                    const StrokePlan& plan,
                                    int stroke,
                                    const std::optional<SpanRect>& missing) {
    const IdentificationRequestMessages m =
        IdentificationRequestToLcm(NowUtime(),
                                   job_id,
                                   request_id,
                                   robot,
                                   material,
                                   fingertip,
                                   plan,
                                   stroke,
                                   missing);
    PublishToRobot(kLcmIdentRequestChannel, m.v1, m.v1.robot);
    // v2: the same plus the LuGre pair.
    PublishToRobot(kLcmIdentRequestV2Channel, m.v2, m.v2.robot);
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
    HandleChunkOrUnavailable(std::move(m), "stroke_chunk_v1");
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
    HandleChunkOrUnavailable(std::move(m), "stroke_chunk_v2");
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
    // The job must exist, be open and belong to the named pair; this
    // daemon must hold its claim (in a fleet one daemon acts on a job).
    std::string field, why;
    std::optional<IdentificationJob> job = library_.jobs().FindOpenFor(
        m.job_id, m.material, fingertip, &field, &why);
    if (!job) return reject(field, why);
    switch (collector_.Admit(*job, m.stroke, NowMonotonicS(), &field, &why)) {
      case ChunkAdmission::kAccept:
        break;
      case ChunkAdmission::kIgnore:
        return;
      case ChunkAdmission::kReject:
        return reject(field, why);
    }
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
    } catch (const RequestError& e) {  // every rejection names its field
      return reject(e.field(), e.what());
    }
    if (outcome == ChunkOutcome::kDuplicate) return;
    collector_.NoteReceiving(&*job, m.stroke, m.robot);
    const StrokeKey key{c.job_id, c.stroke};
    if (outcome == ChunkOutcome::kAccepted) {
      if (auto p = reassembler_.Progress(key))
        PublishProgress(*job,
                        m.robot,
                        *p,
                        JobStateName(JobState::kStroking),
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
    auto job = library_.jobs().Find(e.progress.key.job_id);
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

  // A stroke sender for the service: actor "lcm:<robot>", role "robot" for
  // signed chunks ("" for unsigned ones).
  static StrokeSender SenderOf(const std::string& robot, const char* type) {
    StrokeSender sender;
    sender.robot = robot;
    sender.is_signed = std::string(type) == "stroke_chunk_v2";
    sender.actor = ("lcm:" + robot).substr(0, 128);
    sender.role = sender.is_signed ? "robot" : "";
    sender.action = std::string("LCM ") + type;
    return sender;
  }

  // A complete stroke: the service decides (reject, follow-up, fail, fit);
  // the endpoint tells the robot.
  void OnStrokeComplete(IdentificationJob job,
                        const std::string& robot,
                        const StrokeKey& key,
                        const char* type) {
    const StrokeProgress progress = *reassembler_.Progress(key);
    const StrokeSender sender = SenderOf(robot, type);
    StrokeData stroke;
    try {
      stroke = reassembler_.Take(key);  // the stroke leaves the reassembler
    } catch (const RequestError& e) {
      // Chunks overlapping in time show only once all are in: the robot's
      // error, answered like a rejected chunk (HandleChunk), not internal.
      PublishError(
          type, "", robot, job.id, key.stroke, -1, e.field(), e.what());
      return;
    }
    const StrokeOutcome o =
        collector_.AddStroke(&job, key.stroke, std::move(stroke), sender);
    using Kind = StrokeOutcome::Kind;
    switch (o.kind) {
      case Kind::kRejected:
        PublishError("stroke_chunk_v1",
                     "",
                     robot,
                     job.id,
                     key.stroke,
                     -1,
                     o.field,
                     o.message);
        PublishProgress(
            job, robot, progress, job.state, -1, 0, o.detail, false);
        return;
      case Kind::kNotKept:
        PublishError(
            type, "", robot, job.id, key.stroke, -1, o.field, o.message);
        PublishProgress(
            job, robot, progress, job.state, -1, 0, o.detail, false);
        return;
      case Kind::kFailed:
        PublishProgress(job,
                        robot,
                        progress,
                        JobStateName(o.state),
                        o.span_pct,
                        0,
                        o.detail,
                        false);
        return;
      case Kind::kFollowUp:
        PublishProgress(job,
                        robot,
                        progress,
                        JobStateName(o.state),
                        o.span_pct,
                        0,
                        o.detail,
                        false);
        PublishIdentificationRequest(job.id,
                                     "",
                                     robot,
                                     job.material,
                                     job.fingertip,
                                     IdentificationJobs::PlanOf(job),
                                     o.follow_up_stroke,
                                     o.missing);
        return;
      case Kind::kEnoughCoverage:
      case Kind::kFitted:
        break;
    }
    PublishProgress(job,
                    robot,
                    progress,
                    JobStateName(o.state),
                    o.span_pct,
                    0,
                    o.detail,
                    false);
    struct IngestingJob {  // the model listener reads it on this thread
      explicit IngestingJob(std::int64_t id) { tl_ingesting_job = id; }
      ~IngestingJob() { tl_ingesting_job = 0; }
    };
    StrokeOutcome fit;
    {
      const IngestingJob ingesting(job.id);
      fit = collector_.Fit(&job, o, sender);
    }
    if (fit.kind == Kind::kFailed)
      PublishError("stroke_chunk_v1",
                   "",
                   robot,
                   job.id,
                   key.stroke,
                   -1,
                   fit.field,
                   fit.message);
    PublishProgress(job,
                    robot,
                    progress,
                    JobStateName(fit.state),
                    fit.span_pct,
                    fit.version,
                    fit.detail,
                    false);
  }

  FrictionLibrary& library_;
  LcmEndpointOptions options_;
  // Before lcm_ (declaration order): the sockets open before the provider.
  std::set<std::uint64_t> sockets_before_ = internal::SocketInodes();
  lcm::LCM lcm_;
  std::set<std::uint64_t> lcm_sockets_;  // the provider's UDP sockets
  std::uint64_t kernel_drops_ = 0;       // their drops when last counted
  double next_drop_check_s_ = 0.0;
  std::shared_ptr<LcmPublisher> publisher_;
  StrokeReassembler reassembler_;
  LcmAuthenticator auth_;
  std::string fleet_key_;  // raw; empty: none
  LcmDecodeLimits decode_limits_;
  JobStrokeCollector collector_;
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
