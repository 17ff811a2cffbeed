// The ksvd codec's private half of the learning code: batch OMP over a precomputed Gram matrix
// (Rubinstein, Zibulevsky and Elad, "Efficient Implementation of the K-SVD Algorithm using
// Batch Orthogonal Matching Pursuit", 2008), shared by training and encoding.
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <vector>
#include <voxwall/codec/ksvd_codec.hpp>

namespace voxwall::codec::ksvd {

class Coder {
 public:
  explicit Coder(const Dictionary& dictionary);
  int m() const { return m_; }
  int atoms() const { return k_; }
  // alpha = D^T Y for `count` blocks of m values (one column per block).
  void correlate(const float* blocks, std::size_t count, Eigen::MatrixXf& alpha) const;
  struct Work {  // scratch space, reused across blocks
    std::vector<double> lower, gamma, rhs;
    std::vector<float> alpha;
    std::vector<unsigned char> chosen;
  };
  // One block from its correlations alpha0 (K values) and its energy ||y||^2: atoms are added
  // while fewer than `sparsity`, the squared residual is above maxResidual2 and the next atom
  // takes at least minGain2 off it.
  void code(const float* alpha0, double energy, int sparsity, double maxResidual2, SparseCode& out,
            Work& work, double minGain2 = 0) const;

 private:
  int m_ = 0, k_ = 0;
  Eigen::MatrixXf atoms_;  // m x K
  Eigen::MatrixXf gram_;   // K x K
};

// Codes `count` blocks (m values each, contiguous) on `threads` threads; `advance` (if set) is
// called with the number of blocks each finished chunk held.
void codeAll(const Coder& coder, const float* blocks, std::size_t count, int sparsity,
             double maxResidual2, int threads, std::vector<SparseCode>& codes,
             const std::function<void(std::size_t)>& advance = {}, double minGain2 = 0);

}  // namespace voxwall::codec::ksvd
