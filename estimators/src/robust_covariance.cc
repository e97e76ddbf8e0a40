#include "frictiond/estimators/robust_covariance.h"

#include <map>
#include <stdexcept>
#include <string>

namespace frictiond {

Eigen::MatrixXd CalcClusterRobustCovariance(
    const Eigen::Ref<const Eigen::MatrixXd>& X,
    const Eigen::Ref<const Eigen::VectorXd>& residuals,
    const std::vector<int>& cluster) {
  const Eigen::Index n = X.rows(), k = X.cols();
  if (residuals.size() != n || static_cast<Eigen::Index>(cluster.size()) != n) {
    throw std::invalid_argument(
        "X has " + std::to_string(n) + " rows, residuals " +
        std::to_string(residuals.size()) + ", cluster " +
        std::to_string(cluster.size()) + " (must be equal)");
  }
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(k, k);
  if (k == 0 || n <= k) return P;
  // Score sum X_g' u_g per cluster.
  // Rows come in runs of one cluster (a stroke's samples): one product per
  // run, one map lookup per run.
  std::map<int, Eigen::VectorXd> scores;
  for (Eigen::Index start = 0; start < n;) {
    Eigen::Index end = start + 1;
    while (end < n && cluster[end] == cluster[start]) ++end;
    auto it = scores.find(cluster[start]);
    if (it == scores.end())
      it = scores.emplace(cluster[start], Eigen::VectorXd::Zero(k)).first;
    it->second.noalias() += X.middleRows(start, end - start).transpose() *
                            residuals.segment(start, end - start);
    start = end;
  }
  const double g = static_cast<double>(scores.size());
  if (g < 2) return P;
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(k, k);
  for (const auto& kv : scores)
    meat.noalias() += kv.second * kv.second.transpose();
  const Eigen::MatrixXd xtx = X.transpose() * X;
  Eigen::FullPivLU<Eigen::MatrixXd> lu(xtx);
  if (!lu.isInvertible()) return P;
  const Eigen::MatrixXd bread = lu.inverse();
  const double c = g / (g - 1) * (static_cast<double>(n) - 1) /
                   (static_cast<double>(n) - static_cast<double>(k));
  P = c * bread * meat * bread;
  return 0.5 * (P + P.transpose());
}

}  // namespace frictiond
