#pragma once
/// @file
/// Test helper: an LCM client that records every frictiond message.

#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "frictiond/coverage_progress_v1.hpp"
#include "frictiond/error_v1.hpp"
#include "frictiond/identification_request_v1.hpp"
#include "frictiond/identification_request_v2.hpp"
#include "frictiond/material_query_v1.hpp"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/material_reply_v2.hpp"
#include "frictiond/model_update_v1.hpp"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/stroke_chunk_v1.hpp"

namespace frictiond::testing {

/// Records replies, requests, progress, updates and errors.
class LcmInbox {
 public:
  explicit LcmInbox(const std::string& url) : lcm_(url) {
    lcm_.subscribe(kLcmReplyChannel, &LcmInbox::On<material_reply_v1>, this);
    lcm_.subscribe(kLcmReplyV2Channel, &LcmInbox::On<material_reply_v2>, this);
    lcm_.subscribe(kLcmIdentRequestChannel,
                   &LcmInbox::On<identification_request_v1>,
                   this);
    lcm_.subscribe(kLcmIdentRequestV2Channel,
                   &LcmInbox::On<identification_request_v2>,
                   this);
    lcm_.subscribe(
        kLcmProgressChannel, &LcmInbox::On<coverage_progress_v1>, this);
    lcm_.subscribe(
        kLcmModelUpdateChannel, &LcmInbox::On<model_update_v1>, this);
    lcm_.subscribe(kLcmErrorChannel, &LcmInbox::On<error_v1>, this);
  }
  bool good() const { return lcm_.good(); }
  lcm::LCM& lcm() { return lcm_; }

  /// Pumps messages until `done()` or the timeout; returns done().
  bool WaitFor(const std::function<bool()>& done, double timeout_s = 5.0) {
    const auto end = std::chrono::steady_clock::now() +
                     std::chrono::duration<double>(timeout_s);
    while (!done()) {
      if (std::chrono::steady_clock::now() > end) return false;
      lcm_.handleTimeout(20);
    }
    return true;
  }

  std::vector<material_reply_v1> replies;
  std::vector<material_reply_v2> replies_v2;
  std::vector<identification_request_v1> requests;
  std::vector<identification_request_v2> requests_v2;
  std::vector<coverage_progress_v1> progress;
  std::vector<model_update_v1> updates;
  std::vector<error_v1> errors;

 private:
  template <class M>
  void On(const lcm::ReceiveBuffer*, const std::string&, const M* m) {
    Store(*m);
  }
  void Store(const material_reply_v1& m) { replies.push_back(m); }
  void Store(const material_reply_v2& m) { replies_v2.push_back(m); }
  void Store(const identification_request_v1& m) { requests.push_back(m); }
  void Store(const identification_request_v2& m) { requests_v2.push_back(m); }
  void Store(const coverage_progress_v1& m) { progress.push_back(m); }
  void Store(const model_update_v1& m) { updates.push_back(m); }
  void Store(const error_v1& m) { errors.push_back(m); }

  lcm::LCM lcm_;
};

}  // namespace frictiond::testing
