// Bounds-checked LCM decoders (lcm_codec.h). The wire format is LCM's: an
// 8-byte big-endian type fingerprint, then the fields in declaration order,
// big-endian; a string is an int32 length counting its NUL terminator, the
// bytes and the NUL; a variable array is its elements, counted by an
// earlier int32 field; a nested struct has no fingerprint of its own.
#include "frictiond/proto/lcm_codec.h"

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

namespace frictiond {

const char* LcmDecodeFailureName(LcmDecodeFailure f) {
  switch (f) {
    case LcmDecodeFailure::kNone:
      return "";
    case LcmDecodeFailure::kMalformed:
      return "malformed";
    case LcmDecodeFailure::kTruncated:
      return "truncated";
    case LcmDecodeFailure::kWrongHash:
      return "wrong_hash";
    case LcmDecodeFailure::kOversized:
      return "oversized";
  }
  return "malformed";
}

namespace {

// True when `s` is valid UTF-8 (no overlong forms, no surrogates, <= U+10FFFF).
bool IsValidUtf8(const unsigned char* s, std::size_t n) {
  std::size_t i = 0;
  while (i < n) {
    const unsigned char c = s[i];
    if (c < 0x80) {
      ++i;
      continue;
    }
    int len = 0;
    std::uint32_t cp = 0;
    if ((c & 0xE0) == 0xC0) {
      len = 2;
      cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      len = 3;
      cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      len = 4;
      cp = c & 0x07;
    } else {
      return false;
    }
    if (n - i < static_cast<std::size_t>(len)) return false;
    for (int k = 1; k < len; ++k) {
      const unsigned char d = s[i + k];
      if ((d & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (d & 0x3F);
    }
    if ((len == 2 && cp < 0x80) || (len == 3 && cp < 0x800) ||
        (len == 4 && cp < 0x10000) || cp > 0x10FFFF ||
        (cp >= 0xD800 && cp <= 0xDFFF))
      return false;
    i += static_cast<std::size_t>(len);
  }
  return true;
}

// Reads fields off the buffer; the first failure is kept and every later
// read fails, so a decoder can stop at the first false.
class Reader {
 public:
  Reader(const void* data, std::size_t size, const LcmDecodeLimits& limits)
      : p_(static_cast<const unsigned char*>(data)),
        n_(data ? size : 0),
        limits_(limits) {}

  const LcmDecodeLimits& limits() const { return limits_; }
  const LcmDecodeResult& result() const { return result_; }
  std::size_t left() const { return n_ - pos_; }

  bool Fail(LcmDecodeFailure f,
            const std::string& field,
            const std::string& detail) {
    if (result_.ok()) {
      result_.failure = f;
      result_.field = field;
      result_.detail = field + ": " + detail;
    }
    return false;
  }

  bool Need(const char* field, std::size_t bytes) {
    if (!result_.ok()) return false;
    if (left() < bytes)
      return Fail(LcmDecodeFailure::kTruncated,
                  field,
                  "needs " + std::to_string(bytes) + " bytes, " +
                      std::to_string(left()) + " left (message truncated)");
    return true;
  }

  bool U64(const char* field, std::uint64_t* v) {
    if (!Need(field, 8)) return false;
    std::uint64_t x = 0;
    for (int k = 0; k < 8; ++k) x = (x << 8) | p_[pos_ + k];
    pos_ += 8;
    *v = x;
    return true;
  }
  bool I64(const char* field, std::int64_t* v) {
    std::uint64_t x;
    if (!U64(field, &x)) return false;
    *v = static_cast<std::int64_t>(x);
    return true;
  }
  bool I32(const char* field, std::int32_t* v) {
    if (!Need(field, 4)) return false;
    std::uint32_t x = 0;
    for (int k = 0; k < 4; ++k) x = (x << 8) | p_[pos_ + k];
    pos_ += 4;
    *v = static_cast<std::int32_t>(x);
    return true;
  }
  bool I8(const char* field, std::int8_t* v) {
    if (!Need(field, 1)) return false;
    *v = static_cast<std::int8_t>(p_[pos_++]);
    return true;
  }
  bool Bool(const char* field, std::int8_t* v) {
    std::int8_t x;
    if (!I8(field, &x)) return false;
    if (x != 0 && x != 1)
      return Fail(LcmDecodeFailure::kMalformed,
                  field,
                  "boolean byte " + std::to_string(x) + " (must be 0 or 1)");
    *v = x;
    return true;
  }
  bool F64(const char* field, double* v) {
    std::uint64_t x;
    if (!U64(field, &x)) return false;
    std::memcpy(v, &x, sizeof x);
    return true;
  }
  bool Bytes(const char* field, std::uint8_t* out, std::size_t n) {
    if (!Need(field, n)) return false;
    std::memcpy(out, p_ + pos_, n);
    pos_ += n;
    return true;
  }
  bool String(const char* field, std::string* out) {
    std::int32_t len;
    if (!I32(field, &len)) return false;
    if (len < 1)
      return Fail(LcmDecodeFailure::kMalformed,
                  field,
                  "string length " + std::to_string(len) +
                      " (must be >= 1: the NUL terminator)");
    const std::size_t ulen = static_cast<std::size_t>(len);
    if (ulen - 1 > limits_.max_string_bytes)
      return Fail(LcmDecodeFailure::kOversized,
                  field,
                  "string of " + std::to_string(ulen - 1) + " bytes (at most " +
                      std::to_string(limits_.max_string_bytes) + ")");
    if (!Need(field, ulen)) return false;
    const unsigned char* s = p_ + pos_;
    if (s[ulen - 1] != 0)
      return Fail(LcmDecodeFailure::kMalformed,
                  field,
                  "string does not end in its NUL terminator");
    if (std::memchr(s, 0, ulen - 1) != nullptr)
      return Fail(
          LcmDecodeFailure::kMalformed, field, "string contains a NUL byte");
    if (!IsValidUtf8(s, ulen - 1))
      return Fail(LcmDecodeFailure::kMalformed, field, "not valid UTF-8");
    out->assign(reinterpret_cast<const char*>(s), ulen - 1);
    pos_ += ulen;
    return true;
  }
  // An array count: >= 0, <= max, and `elem_bytes` * count * `arrays`
  // bytes must be left (each element is at least elem_bytes long).
  bool Count(const char* field,
             std::int32_t n,
             std::int64_t max,
             std::size_t elem_bytes,
             std::size_t arrays = 1) {
    if (!result_.ok()) return false;
    if (n < 0)
      return Fail(LcmDecodeFailure::kMalformed,
                  field,
                  std::to_string(n) + " (an array count must be >= 0)");
    if (n > max)
      return Fail(LcmDecodeFailure::kOversized,
                  field,
                  std::to_string(n) + " (at most " + std::to_string(max) + ")");
    const std::size_t need = static_cast<std::size_t>(n) * elem_bytes * arrays;
    if (left() < need)
      return Fail(LcmDecodeFailure::kTruncated,
                  field,
                  std::to_string(n) + " elements need at least " +
                      std::to_string(need) + " bytes, " +
                      std::to_string(left()) + " left (message truncated)");
    return true;
  }
  bool F64Array(const char* field, std::int32_t n, std::vector<double>* out) {
    if (!Need(field, static_cast<std::size_t>(n) * 8)) return false;
    out->resize(static_cast<std::size_t>(n));
    for (double& x : *out) F64(field, &x);
    return true;
  }
  bool I32Array(const char* field, std::int32_t n, std::vector<int32_t>* out) {
    if (!Need(field, static_cast<std::size_t>(n) * 4)) return false;
    out->resize(static_cast<std::size_t>(n));
    for (std::int32_t& x : *out) I32(field, &x);
    return true;
  }
  bool ByteArray(const char* field,
                 std::int32_t n,
                 std::vector<std::uint8_t>* out) {
    if (!Need(field, static_cast<std::size_t>(n))) return false;
    out->assign(p_ + pos_, p_ + pos_ + n);
    pos_ += static_cast<std::size_t>(n);
    return true;
  }
  bool StringArray(const char* field,
                   std::int32_t n,
                   std::vector<std::string>* out) {
    out->clear();
    out->reserve(static_cast<std::size_t>(n));  // n * 5 bytes are left
    for (std::int32_t i = 0; i < n; ++i) {
      std::string s;
      const std::string name =
          std::string(field) + "[" + std::to_string(i) + "]";
      if (!String(name.c_str(), &s)) return false;
      out->push_back(std::move(s));
    }
    return true;
  }
  bool Fingerprint(std::int64_t expected, const char* type) {
    if (n_ > limits_.max_message_bytes)
      return Fail(LcmDecodeFailure::kOversized,
                  "(message)",
                  std::to_string(n_) + " bytes (at most " +
                      std::to_string(limits_.max_message_bytes) + ")");
    std::int64_t h;
    if (!I64("(fingerprint)", &h)) return false;
    if (h != expected)
      return Fail(LcmDecodeFailure::kWrongHash,
                  "(fingerprint)",
                  std::string("not a ") + type +
                      " (wrong type fingerprint: another type or version)");
    return true;
  }
  bool End() {
    if (!result_.ok()) return false;
    if (left() != 0)
      return Fail(
          LcmDecodeFailure::kMalformed,
          "(message)",
          std::to_string(left()) + " bytes after the end of the message");
    return true;
  }

 private:
  const unsigned char* p_;
  std::size_t n_;
  std::size_t pos_ = 0;
  const LcmDecodeLimits& limits_;
  LcmDecodeResult result_;
};

#define FRICTIOND_READ(expr) \
  if (!(expr)) return false

bool Fields(Reader& r, friction_model_v1* m) {
  FRICTIOND_READ(r.String("model.material", &m->material));
  FRICTIOND_READ(r.String("model.fingertip", &m->fingertip));
  FRICTIOND_READ(r.I32("model.version", &m->version));
  FRICTIOND_READ(r.String("model.created_at", &m->created_at));
  FRICTIOND_READ(r.I32("model.n_terms", &m->n_terms));
  // term_names (>= 5 bytes each), coefficients and std_errors (8 each).
  FRICTIOND_READ(
      r.Count("model.n_terms", m->n_terms, r.limits().max_terms, 21));
  FRICTIOND_READ(r.StringArray("model.term_names", m->n_terms, &m->term_names));
  FRICTIOND_READ(
      r.F64Array("model.coefficients", m->n_terms, &m->coefficients));
  FRICTIOND_READ(r.F64Array("model.std_errors", m->n_terms, &m->std_errors));
  FRICTIOND_READ(r.F64("model.sigma_eps", &m->sigma_eps));
  FRICTIOND_READ(r.F64("model.r2", &m->r2));
  FRICTIOND_READ(r.I32("model.samples", &m->samples));
  FRICTIOND_READ(r.I32("model.n_quantiles", &m->n_quantiles));
  FRICTIOND_READ(r.Count(
      "model.n_quantiles", m->n_quantiles, r.limits().max_quantiles, 8, 2));
  FRICTIOND_READ(
      r.F64Array("model.eps_levels", m->n_quantiles, &m->eps_levels));
  FRICTIOND_READ(
      r.F64Array("model.eps_quantiles", m->n_quantiles, &m->eps_quantiles));
  FRICTIOND_READ(r.F64("model.mu_coulomb", &m->mu_coulomb));
  FRICTIOND_READ(r.F64("model.likelihood_c1", &m->likelihood_c1));
  FRICTIOND_READ(r.F64("model.likelihood_c2", &m->likelihood_c2));
  FRICTIOND_READ(r.Bool("model.has_lugre", &m->has_lugre));
  for (double& x : m->lugre_theta)
    FRICTIOND_READ(r.F64("model.lugre_theta", &x));
  return true;
}

bool Fields(Reader& r, material_query_v1* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.String("request_id", &m->request_id));
  FRICTIOND_READ(r.String("robot", &m->robot));
  FRICTIOND_READ(r.String("material", &m->material));
  FRICTIOND_READ(r.String("fingertip", &m->fingertip));
  FRICTIOND_READ(r.I32("image_size", &m->image_size));
  FRICTIOND_READ(r.Count("image_size",
                         m->image_size,
                         static_cast<std::int64_t>(r.limits().max_image_bytes),
                         1));
  return r.ByteArray("image", m->image_size, &m->image);
}

bool Fields(Reader& r, material_reply_v1* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.String("request_id", &m->request_id));
  FRICTIOND_READ(r.String("robot", &m->robot));
  FRICTIOND_READ(r.String("material", &m->material));
  FRICTIOND_READ(r.String("fingertip", &m->fingertip));
  FRICTIOND_READ(r.I8("status", &m->status));
  FRICTIOND_READ(r.String("reason", &m->reason));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.F64("recognition_score", &m->recognition_score));
  return Fields(r, &m->model);
}

bool Fields(Reader& r, material_reply_v2* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.String("request_id", &m->request_id));
  FRICTIOND_READ(r.String("robot", &m->robot));
  FRICTIOND_READ(r.String("material", &m->material));
  FRICTIOND_READ(r.String("fingertip", &m->fingertip));
  FRICTIOND_READ(r.I8("status", &m->status));
  FRICTIOND_READ(r.String("reason", &m->reason));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.F64("recognition_score", &m->recognition_score));
  FRICTIOND_READ(Fields(r, &m->model));
  FRICTIOND_READ(r.Bool("recognition_unknown", &m->recognition_unknown));
  FRICTIOND_READ(r.String("recognition_reason", &m->recognition_reason));
  FRICTIOND_READ(
      r.F64("recognition_operating_point", &m->recognition_operating_point));
  FRICTIOND_READ(r.I32("n_candidates", &m->n_candidates));
  // candidate_material (>= 5 bytes each: length + NUL), candidate_score (8).
  FRICTIOND_READ(
      r.Count("n_candidates", m->n_candidates, r.limits().max_candidates, 13));
  FRICTIOND_READ(r.StringArray(
      "candidate_material", m->n_candidates, &m->candidate_material));
  return r.F64Array("candidate_score", m->n_candidates, &m->candidate_score);
}

template <class Request>
bool CommonRequestFields(Reader& r, Request* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.I32("stroke", &m->stroke));
  FRICTIOND_READ(r.String("request_id", &m->request_id));
  FRICTIOND_READ(r.String("robot", &m->robot));
  FRICTIOND_READ(r.String("material", &m->material));
  FRICTIOND_READ(r.String("fingertip", &m->fingertip));
  FRICTIOND_READ(r.F64("fn_min_n", &m->fn_min_n));
  FRICTIOND_READ(r.F64("fn_max_n", &m->fn_max_n));
  FRICTIOND_READ(r.F64("v_min_mm_s", &m->v_min_mm_s));
  FRICTIOND_READ(r.F64("v_max_mm_s", &m->v_max_mm_s));
  FRICTIOND_READ(r.F64("max_duration_s", &m->max_duration_s));
  FRICTIOND_READ(r.F64("min_span_pct", &m->min_span_pct));
  FRICTIOND_READ(r.Bool("follow_up", &m->follow_up));
  return r.String("instructions", &m->instructions);
}

bool Fields(Reader& r, identification_request_v1* m) {
  return CommonRequestFields(r, m);
}

bool Fields(Reader& r, identification_request_v2* m) {
  FRICTIOND_READ(CommonRequestFields(r, m));
  FRICTIOND_READ(r.Bool("lugre_pair", &m->lugre_pair));
  FRICTIOND_READ(r.F64("lugre_fn_n", &m->lugre_fn_n));
  FRICTIOND_READ(r.F64("lugre_slow_accel_mm_s2", &m->lugre_slow_accel_mm_s2));
  FRICTIOND_READ(r.F64("lugre_slow_peak_mm_s", &m->lugre_slow_peak_mm_s));
  FRICTIOND_READ(r.I32("lugre_fast_strokes", &m->lugre_fast_strokes));
  FRICTIOND_READ(r.F64("lugre_fast_accel_mm_s2", &m->lugre_fast_accel_mm_s2));
  FRICTIOND_READ(r.F64("lugre_fast_peak_mm_s", &m->lugre_fast_peak_mm_s));
  return r.F64("lugre_rest_s", &m->lugre_rest_s);
}

// The fields stroke_chunk_v1 and _v2 share after job_id/stroke.
template <class Chunk>
bool ChunkBody(Reader& r, Chunk* m) {
  FRICTIOND_READ(r.String("robot", &m->robot));
  FRICTIOND_READ(r.String("material", &m->material));
  FRICTIOND_READ(r.String("fingertip", &m->fingertip));
  FRICTIOND_READ(r.I32("seq", &m->seq));
  FRICTIOND_READ(r.I32("total_chunks", &m->total_chunks));
  FRICTIOND_READ(r.Bool("last", &m->last));
  FRICTIOND_READ(r.I32("n_samples", &m->n_samples));
  FRICTIOND_READ(
      r.Count("n_samples", m->n_samples, r.limits().max_samples, 8, 4));
  FRICTIOND_READ(r.F64Array("t_s", m->n_samples, &m->t_s));
  FRICTIOND_READ(r.F64Array("fn_n", m->n_samples, &m->fn_n));
  FRICTIOND_READ(r.F64Array("ft_n", m->n_samples, &m->ft_n));
  return r.F64Array("v_mm_s", m->n_samples, &m->v_mm_s);
}

bool Fields(Reader& r, stroke_chunk_v1* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.I32("stroke", &m->stroke));
  return ChunkBody(r, m);
}

bool Fields(Reader& r, stroke_chunk_v2* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.Bytes("nonce", m->nonce, sizeof m->nonce));
  FRICTIOND_READ(r.Bytes("hmac", m->hmac, sizeof m->hmac));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.I32("stroke", &m->stroke));
  return ChunkBody(r, m);
}

bool Fields(Reader& r, coverage_progress_v1* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.I32("stroke", &m->stroke));
  FRICTIOND_READ(r.String("material", &m->material));
  FRICTIOND_READ(r.String("fingertip", &m->fingertip));
  FRICTIOND_READ(r.String("robot", &m->robot));
  FRICTIOND_READ(r.String("state", &m->state));
  FRICTIOND_READ(r.I32("chunks_received", &m->chunks_received));
  FRICTIOND_READ(r.I32("chunks_expected", &m->chunks_expected));
  FRICTIOND_READ(r.I32("n_missing", &m->n_missing));
  FRICTIOND_READ(r.Count("n_missing", m->n_missing, r.limits().max_missing, 4));
  FRICTIOND_READ(r.I32Array("missing_seqs", m->n_missing, &m->missing_seqs));
  FRICTIOND_READ(r.I64("samples", &m->samples));
  FRICTIOND_READ(r.F64("span_pct", &m->span_pct));
  FRICTIOND_READ(r.F64("min_span_pct", &m->min_span_pct));
  FRICTIOND_READ(r.I32("model_version", &m->model_version));
  return r.String("detail", &m->detail);
}

bool Fields(Reader& r, model_update_v1* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.String("reason", &m->reason));
  return Fields(r, &m->model);
}

bool Fields(Reader& r, error_v1* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.String("message_type", &m->message_type));
  FRICTIOND_READ(r.String("request_id", &m->request_id));
  FRICTIOND_READ(r.String("robot", &m->robot));
  FRICTIOND_READ(r.I64("job_id", &m->job_id));
  FRICTIOND_READ(r.I32("stroke", &m->stroke));
  FRICTIOND_READ(r.I32("seq", &m->seq));
  FRICTIOND_READ(r.String("field", &m->field));
  return r.String("reason", &m->reason);
}

bool Fields(Reader& r, signed_message_v1* m) {
  FRICTIOND_READ(r.I64("utime", &m->utime));
  FRICTIOND_READ(r.Bytes("nonce", m->nonce, sizeof m->nonce));
  FRICTIOND_READ(r.Bytes("hmac", m->hmac, sizeof m->hmac));
  FRICTIOND_READ(r.String("key_id", &m->key_id));
  FRICTIOND_READ(r.String("channel", &m->channel));
  FRICTIOND_READ(r.I32("payload_size", &m->payload_size));
  FRICTIOND_READ(
      r.Count("payload_size",
              m->payload_size,
              static_cast<std::int64_t>(r.limits().max_payload_bytes),
              1));
  return r.ByteArray("payload", m->payload_size, &m->payload);
}

#undef FRICTIOND_READ

template <class Message>
LcmDecodeResult Decode(const void* data,
                       std::size_t size,
                       Message* out,
                       const LcmDecodeLimits& limits,
                       const char* type) {
  *out = Message();
  Reader r(data, size, limits);
  if (r.Fingerprint(Message::getHash(), type) && Fields(r, out)) r.End();
  return r.result();
}

}  // namespace

#define FRICTIOND_DECODER(Type)                              \
  LcmDecodeResult DecodeLcm(const void* data,                \
                            std::size_t size,                \
                            Type* out,                       \
                            const LcmDecodeLimits& limits) { \
    return Decode(data, size, out, limits, #Type);           \
  }
FRICTIOND_DECODER(material_query_v1)
FRICTIOND_DECODER(material_reply_v1)
FRICTIOND_DECODER(material_reply_v2)
FRICTIOND_DECODER(identification_request_v1)
FRICTIOND_DECODER(identification_request_v2)
FRICTIOND_DECODER(stroke_chunk_v1)
FRICTIOND_DECODER(stroke_chunk_v2)
FRICTIOND_DECODER(coverage_progress_v1)
FRICTIOND_DECODER(model_update_v1)
FRICTIOND_DECODER(error_v1)
FRICTIOND_DECODER(signed_message_v1)
#undef FRICTIOND_DECODER

material_reply_v2 MakeMaterialReplyV2(const material_reply_v1& v1,
                                      const LcmRecognition* recognition,
                                      std::int32_t max_candidates) {
  material_reply_v2 m;
  m.utime = v1.utime;
  m.request_id = v1.request_id;
  m.robot = v1.robot;
  m.material = v1.material;
  m.fingertip = v1.fingertip;
  m.status = v1.status;
  m.reason = v1.reason;
  m.job_id = v1.job_id;
  m.recognition_score = v1.recognition_score;
  m.model = v1.model;
  m.recognition_unknown = true;
  m.recognition_operating_point = 0.0;
  m.n_candidates = 0;
  if (recognition != nullptr) {
    m.recognition_unknown = recognition->unknown;
    m.recognition_reason = recognition->reason;
    m.recognition_operating_point = recognition->operating_point;
    const std::size_t n =
        std::min(recognition->candidates.size(),
                 static_cast<std::size_t>(std::max(max_candidates, 0)));
    for (std::size_t i = 0; i < n; ++i) {
      m.candidate_material.push_back(recognition->candidates[i].first);
      m.candidate_score.push_back(recognition->candidates[i].second);
    }
    m.n_candidates = static_cast<std::int32_t>(n);
  }
  return m;
}

}  // namespace frictiond
