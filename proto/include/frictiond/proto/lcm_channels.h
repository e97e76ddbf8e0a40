#pragma once
/// @file
/// LCM channel names of frictiond (docs/lcm.md). The message types are
/// generated from proto/*.lcm (package frictiond); each channel carries one
/// versioned type, and a new version gets a new channel (..._V2) so that old
/// robots keep working.

namespace frictiond {

/// Robot -> daemon: material_query_v1.
inline constexpr const char* kLcmQueryChannel = "FRICTIOND_QUERY_V1";
/// Daemon -> robot: material_reply_v1.
inline constexpr const char* kLcmReplyChannel = "FRICTIOND_REPLY_V1";
/// Daemon -> robot: material_reply_v2 (v1's reply plus the recognition's
/// verdict, reason and candidates), published beside v1.
inline constexpr const char* kLcmReplyV2Channel = "FRICTIOND_REPLY_V2";
/// Daemon -> robot: identification_request_v1 (the test stroke to perform).
inline constexpr const char* kLcmIdentRequestChannel =
    "FRICTIOND_IDENT_REQUEST_V1";
/// Daemon -> robot: identification_request_v2 (v1's stroke plan plus the
/// LuGre identifying pair), published beside v1.
inline constexpr const char* kLcmIdentRequestV2Channel =
    "FRICTIOND_IDENT_REQUEST_V2";
/// Robot -> daemon: stroke_chunk_v1 (unsigned; accepted only when the daemon
/// runs with lcm_allow_unsigned).
inline constexpr const char* kLcmStrokeChannel = "FRICTIOND_STROKE_V1";
/// Robot -> daemon: stroke_chunk_v2 (signed with the robot's HMAC key).
inline constexpr const char* kLcmSignedStrokeChannel = "FRICTIOND_STROKE_V2";
/// Daemon -> robot: coverage_progress_v1 (also the resend request).
inline constexpr const char* kLcmProgressChannel = "FRICTIOND_PROGRESS_V1";
/// Daemon -> fleet: model_update_v1.
inline constexpr const char* kLcmModelUpdateChannel =
    "FRICTIOND_MODEL_UPDATE_V1";
/// Daemon -> sender: error_v1 (a rejected message, nothing stored); signed
/// on the "_SIGNED" channel, unsigned only with lcm_send_unsigned.
inline constexpr const char* kLcmErrorChannel = "FRICTIOND_ERROR_V1";

}  // namespace frictiond
