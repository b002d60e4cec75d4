#include <cuda_runtime.h>

#include <cub/block/block_reduce.cuh>
#include <atomic>
#include <string>

#include "gcmap/core/error.hpp"
#include "gcmap/cuda/kernels.hpp"

namespace gcmap::cuda::device {

namespace {

constexpr int kThreads = 256;

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw Error(std::string("CUDA ") + what + ": " + cudaGetErrorString(e));
}

// Each host thread works in its own stream: the scans prepared on several threads, the odometry's
// registrations and the mapper's batches run side by side instead of queueing behind each other in
// the legacy default stream. Memory comes from the stream-ordered pool, because cudaFree waits for
// the whole device. Every call of this file's interface ends with its stream drained, so what one
// call wrote is complete before another thread's stream reads or frees it.
cudaStream_t stream() { return cudaStreamPerThread; }

// Devices without the pool (some virtualized ones) allocate the plain way. Set by select_device.
std::atomic<bool> use_pool{false};

void drain(const char* what) {
  check(cudaGetLastError(), what);
  check(cudaStreamSynchronize(stream()), what);
}

template <class T>
T* device_alloc(size_t n) {
  void* p = nullptr;
  if (n > 0 && use_pool) check(cudaMallocAsync(&p, n * sizeof(T), stream()), "cudaMallocAsync");
  if (n > 0 && !use_pool) check(cudaMalloc(&p, n * sizeof(T)), "cudaMalloc");
  return static_cast<T*>(p);
}

template <class T>
void device_free(T*& p) {
  if (p) use_pool ? cudaFreeAsync(p, stream()) : cudaFree(p);
  p = nullptr;
}

template <class T>
void upload(T* dst, const T* src, size_t n) {
  if (n > 0) check(cudaMemcpyAsync(dst, src, n * sizeof(T), cudaMemcpyHostToDevice, stream()), "upload");
}

template <class T>
void download(T* dst, const T* src, size_t n, const char* what) {
  if (n > 0) check(cudaMemcpyAsync(dst, src, n * sizeof(T), cudaMemcpyDeviceToHost, stream()), what);
  drain(what);
}

// What a block needs of its pair, in one struct so a block reads it with one load.
struct PairView {
  const float* means;  // source, 4 per point
  const float* covs;   // source, 6 per point
  uint32_t num_points;
  uint32_t point_offset;  // into voxel_of_point
  VoxelMap target;
  float c2;  // robust width squared; 0: none
};

// Rounded like PointTransform (core/gaussian_voxel_map.hpp): no fused multiply-add.
__device__ __forceinline__ float3 transform_point(const float* T, float x, float y, float z) {
  const auto row = [&](int r) {
    return __fadd_rn(__fadd_rn(__fadd_rn(__fmul_rn(T[4 * r], x), __fmul_rn(T[4 * r + 1], y)), __fmul_rn(T[4 * r + 2], z)),
                     T[4 * r + 3]);
  };
  return make_float3(row(0), row(1), row(2));
}

__device__ __forceinline__ int32_t lookup(const VoxelMap& m, float3 q) {
  return voxel_table_find(m.slots, m.mask, static_cast<int32_t>(floorf(__fmul_rn(q.x, m.inv_resolution))),
                          static_cast<int32_t>(floorf(__fmul_rn(q.y, m.inv_resolution))),
                          static_cast<int32_t>(floorf(__fmul_rn(q.z, m.inv_resolution))));
}

// Symmetric 3x3 as (xx xy xz yy yz zz).
struct Sym3 {
  float a[6];
};

// Fused covariance S = C_v + R C R^T, inverted by cofactors; false when |det| <= 1e-12 (the
// threshold the CPU path's Eigen check uses).
__device__ __forceinline__ bool fused_information(const float* T, const float* C, const float* Cv, Sym3& W) {
  // M = R C (full), S = M R^T + C_v.
  const float c[3][3] = {{C[0], C[1], C[2]}, {C[1], C[3], C[4]}, {C[2], C[4], C[5]}};
  float M[3][3];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) M[r][k] = T[4 * r] * c[0][k] + T[4 * r + 1] * c[1][k] + T[4 * r + 2] * c[2][k];
  float S[6];
  const int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
  for (int k = 0; k < 6; ++k) {
    const int r = idx[k][0], s = idx[k][1];
    S[k] = M[r][0] * T[4 * s] + M[r][1] * T[4 * s + 1] + M[r][2] * T[4 * s + 2] + Cv[k];
  }
  const float c00 = S[3] * S[5] - S[4] * S[4];
  const float c01 = S[2] * S[4] - S[1] * S[5];
  const float c02 = S[1] * S[4] - S[2] * S[3];
  const float det = S[0] * c00 + S[1] * c01 + S[2] * c02;
  if (!(fabsf(det) > 1e-12f)) return false;
  const float inv = 1.f / det;
  W.a[0] = c00 * inv;
  W.a[1] = c01 * inv;
  W.a[2] = c02 * inv;
  W.a[3] = (S[0] * S[5] - S[2] * S[2]) * inv;
  W.a[4] = (S[1] * S[2] - S[0] * S[4]) * inv;
  W.a[5] = (S[0] * S[3] - S[1] * S[1]) * inv;
  return true;
}

// With c2 > 0: W scaled by the IRLS weight c2 / (c2 + m2) and Cauchy's cost c2 log(1 + m2 / c2), as
// registration/gaussian_terms.hpp; else the cost m2.
__device__ __forceinline__ float robust_cost(const float e[3], float c2, Sym3& W) {
  const float* w = W.a;
  const float m2 = e[0] * (w[0] * e[0] + w[1] * e[1] + w[2] * e[2]) + e[1] * (w[1] * e[0] + w[3] * e[1] + w[4] * e[2]) +
                   e[2] * (w[2] * e[0] + w[4] * e[1] + w[5] * e[2]);
  if (!(c2 > 0.f)) return m2;
  const float weight = c2 / (c2 + m2);
  for (int k = 0; k < 6; ++k) W.a[k] *= weight;
  return c2 * log1pf(m2 / c2);
}

struct Sums {
  float v[kSums];
};
struct AddSums {
  __device__ __forceinline__ Sums operator()(const Sums& a, const Sums& b) const {
    Sums r;
#pragma unroll
    for (int k = 0; k < kSums; ++k) r.v[k] = a.v[k] + b.v[k];
    return r;
  }
};

// Adds one point's terms in the target frame: e = mu_v - q, B = [-[q]x, I],
// H += B^T W B, b += B^T W e (as in registration/gaussian_terms.hpp).
__device__ __forceinline__ void accumulate(float3 q, float3 e, const Sym3& w, float cost, Sums& s) {
  const float W[3][3] = {{w.a[0], w.a[1], w.a[2]}, {w.a[1], w.a[3], w.a[4]}, {w.a[2], w.a[4], w.a[5]}};
  const float Q[3][3] = {{0.f, -q.z, q.y}, {q.z, 0.f, -q.x}, {-q.y, q.x, 0.f}};
  float QW[3][3];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) QW[r][k] = Q[r][0] * W[0][k] + Q[r][1] * W[1][k] + Q[r][2] * W[2][k];
  const int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
  for (int k = 0; k < 6; ++k) {
    const int r = idx[k][0], c = idx[k][1];
    s.v[k] = -(QW[r][0] * Q[0][c] + QW[r][1] * Q[1][c] + QW[r][2] * Q[2][c]);
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) s.v[6 + 3 * r + c] = QW[r][c];
  for (int k = 0; k < 6; ++k) s.v[15 + k] = w.a[k];
  const float We[3] = {W[0][0] * e.x + W[0][1] * e.y + W[0][2] * e.z, W[1][0] * e.x + W[1][1] * e.y + W[1][2] * e.z,
                       W[2][0] * e.x + W[2][1] * e.y + W[2][2] * e.z};
  for (int r = 0; r < 3; ++r) s.v[21 + r] = Q[r][0] * We[0] + Q[r][1] * We[1] + Q[r][2] * We[2];
  for (int r = 0; r < 3; ++r) s.v[24 + r] = We[r];
  s.v[27] = cost;
  s.v[28] = 1.f;
}

// The block's pair, and its pose staged in shared memory for all threads.
__device__ __forceinline__ PairView block_pair_and_pose(const PairView* pairs, const int32_t* block_pair, const float* poses,
                                                        float* T) {
  const int pair = block_pair[blockIdx.x];
  if (threadIdx.x < 12) T[threadIdx.x] = poses[12 * pair + threadIdx.x];
  __syncthreads();
  return pairs[pair];
}

__global__ void linearize_kernel(const PairView* pairs, const int32_t* block_pair, const uint32_t* block_begin,
                                 const float* poses, int32_t* voxel_of_point, float* block_sums) {
  using Reduce = cub::BlockReduce<Sums, kThreads>;
  __shared__ typename Reduce::TempStorage scratch;
  __shared__ float T[12];
  const PairView P = block_pair_and_pose(pairs, block_pair, poses, T);
  Sums s;
#pragma unroll
  for (int k = 0; k < kSums; ++k) s.v[k] = 0.f;
  const uint32_t i = block_begin[blockIdx.x] + threadIdx.x;
  if (i < P.num_points) {
    const float* p = P.means + 4 * static_cast<size_t>(i);
    const float3 q = transform_point(T, p[0], p[1], p[2]);
    const int32_t v = lookup(P.target, q);
    voxel_of_point[P.point_offset + i] = v;
    Sym3 W;
    if (v >= 0 && fused_information(T, P.covs + 6 * static_cast<size_t>(i), P.target.covs + 6 * static_cast<size_t>(v), W)) {
      const float* mu = P.target.means + 4 * static_cast<size_t>(v);
      const float e[3] = {mu[0] - q.x, mu[1] - q.y, mu[2] - q.z};
      const float cost = robust_cost(e, P.c2, W);
      accumulate(q, make_float3(e[0], e[1], e[2]), W, cost, s);
    }
  }
  const Sums total = Reduce(scratch).Reduce(s, AddSums());
  if (threadIdx.x == 0) {
    for (int k = 0; k < kSums; ++k) block_sums[static_cast<size_t>(blockIdx.x) * kSums + k] = total.v[k];
  }
}

// One block per pair; thread k sums entry k of the pair's blocks in double, in block order.
__global__ void pair_sums_kernel(const uint32_t* pair_first_block, const float* block_sums, int width, double* out) {
  const int pair = blockIdx.x;
  const int k = threadIdx.x;
  if (k >= width) return;
  double acc = 0.0;
  for (uint32_t b = pair_first_block[pair]; b < pair_first_block[pair + 1]; ++b)
    acc += block_sums[static_cast<size_t>(b) * width + k];
  out[static_cast<size_t>(pair) * width + k] = acc;
}

struct ErrorSums {
  float error, inliers;
};
struct AddErrorSums {
  __device__ __forceinline__ ErrorSums operator()(const ErrorSums& a, const ErrorSums& b) const {
    return {a.error + b.error, a.inliers + b.inliers};
  }
};

__global__ void trial_kernel(const PairView* pairs, const int32_t* block_pair, const uint32_t* block_begin, const float* poses,
                             const int32_t* voxel_of_point, float* block_sums) {
  using Reduce = cub::BlockReduce<ErrorSums, kThreads>;
  __shared__ typename Reduce::TempStorage scratch;
  __shared__ float T[12];
  const PairView P = block_pair_and_pose(pairs, block_pair, poses, T);
  ErrorSums s{0.f, 0.f};
  const uint32_t i = block_begin[blockIdx.x] + threadIdx.x;
  if (i < P.num_points) {
    const int32_t v = voxel_of_point[P.point_offset + i];
    Sym3 W;
    if (v >= 0 && fused_information(T, P.covs + 6 * static_cast<size_t>(i), P.target.covs + 6 * static_cast<size_t>(v), W)) {
      const float* p = P.means + 4 * static_cast<size_t>(i);
      const float3 q = transform_point(T, p[0], p[1], p[2]);
      const float* mu = P.target.means + 4 * static_cast<size_t>(v);
      const float e[3] = {mu[0] - q.x, mu[1] - q.y, mu[2] - q.z};
      s.error = robust_cost(e, P.c2, W);
      s.inliers = 1.f;
    }
  }
  const ErrorSums total = Reduce(scratch).Reduce(s, AddErrorSums());
  if (threadIdx.x == 0) {
    block_sums[2 * static_cast<size_t>(blockIdx.x)] = total.error;
    block_sums[2 * static_cast<size_t>(blockIdx.x) + 1] = total.inliers;
  }
}

__global__ void build_table_kernel(VoxelSlot* slots, uint32_t mask, const int32_t* coords, uint32_t n, int* failed) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const auto claim = [](int32_t* field, int32_t index) { return atomicCAS(field, -1, index) == -1; };
  if (!voxel_table_insert(slots, mask, coords[3 * i], coords[3 * i + 1], coords[3 * i + 2], static_cast<int32_t>(i), claim))
    *failed = 1;
}

// gridDim.x = blocks_per_target * num_targets.
__global__ void overlap_kernel(const float* means, uint32_t n, const VoxelMap* targets, const float* poses,
                               uint32_t blocks_per_target, uint32_t* block_hits) {
  using Reduce = cub::BlockReduce<uint32_t, kThreads>;
  __shared__ typename Reduce::TempStorage scratch;
  const uint32_t target = blockIdx.x / blocks_per_target;
  const uint32_t i = (blockIdx.x % blocks_per_target) * kThreads + threadIdx.x;
  uint32_t hit = 0;
  if (i < n) {
    const float* p = means + 4 * static_cast<size_t>(i);
    hit = lookup(targets[target], transform_point(poses + 12 * target, p[0], p[1], p[2])) >= 0;
  }
  const uint32_t total = Reduce(scratch).Sum(hit);
  if (threadIdx.x == 0) block_hits[blockIdx.x] = total;
}

// The k nearest neighbours of one point (itself included), kept sorted in registers while the
// block streams the cloud through shared memory in tiles.
__device__ int nearest_neighbors(const float4* means, uint32_t n, float4 q, int k, uint32_t* idx, float* d2, bool active) {
  __shared__ float4 tile[kThreads];
  int found = 0;
  for (uint32_t base = 0; base < n; base += kThreads) {
    const uint32_t j = base + threadIdx.x;
    if (j < n) tile[threadIdx.x] = means[j];
    __syncthreads();
    const uint32_t count = min(static_cast<uint32_t>(kThreads), n - base);
    for (uint32_t t = 0; active && t < count; ++t) {
      const float dx = tile[t].x - q.x, dy = tile[t].y - q.y, dz = tile[t].z - q.z;
      const float d = dx * dx + dy * dy + dz * dz;
      if (found == k && d >= d2[k - 1]) continue;
      int pos = found < k ? found++ : k - 1;
      while (pos > 0 && d2[pos - 1] > d) {  // ties keep the lower index first, as the scan order gives
        d2[pos] = d2[pos - 1];
        idx[pos] = idx[pos - 1];
        --pos;
      }
      d2[pos] = d;
      idx[pos] = base + t;
    }
    __syncthreads();
  }
  return found;
}

// Unit eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix (cyclic Jacobi in double).
__device__ void smallest_eigenvector(double A[3][3], double v[3]) {
  double V[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int sweep = 0; sweep < 12; ++sweep) {
    const double off = A[0][1] * A[0][1] + A[0][2] * A[0][2] + A[1][2] * A[1][2];
    if (off <= 1e-30 * (A[0][0] * A[0][0] + A[1][1] * A[1][1] + A[2][2] * A[2][2]) + 1e-300) break;
    for (int p = 0; p < 2; ++p) {
      for (int q = p + 1; q < 3; ++q) {
        if (A[p][q] == 0.0) continue;
        const double theta = (A[q][q] - A[p][p]) / (2.0 * A[p][q]);
        const double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
        const double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
        for (int r = 0; r < 3; ++r) {  // A <- A J
          const double arp = A[r][p], arq = A[r][q];
          A[r][p] = c * arp - s * arq;
          A[r][q] = s * arp + c * arq;
        }
        for (int r = 0; r < 3; ++r) {  // A <- J^T A
          const double apr = A[p][r], aqr = A[q][r];
          A[p][r] = c * apr - s * aqr;
          A[q][r] = s * apr + c * aqr;
        }
        for (int r = 0; r < 3; ++r) {
          const double vrp = V[r][p], vrq = V[r][q];
          V[r][p] = c * vrp - s * vrq;
          V[r][q] = s * vrp + c * vrq;
        }
      }
    }
  }
  int m = 0;
  for (int i = 1; i < 3; ++i)
    if (A[i][i] < A[m][m]) m = i;
  for (int r = 0; r < 3; ++r) v[r] = V[r][m];
}

__global__ void covariance_kernel(const float4* means, uint32_t n, int k, double epsilon, double elevation_sigma, float* covs) {
  const uint32_t i = blockIdx.x * kThreads + threadIdx.x;
  const bool active = i < n;
  const float4 q = means[active ? i : 0];
  uint32_t idx[kMaxNeighbors];
  float d2[kMaxNeighbors];
  const int found = nearest_neighbors(means, n, q, k, idx, d2, active);
  if (!active) return;
  float* out = covs + 6 * static_cast<size_t>(i);
  if (found < 4) {  // as the CPU: too few neighbours for a shape
    const float iso[6] = {0.01f, 0.f, 0.f, 0.01f, 0.f, 0.01f};
    for (int c = 0; c < 6; ++c) out[c] = iso[c];
    return;
  }
  double sum[3] = {0, 0, 0}, sum2[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  for (int j = 0; j < found; ++j) {
    const float4 p = means[idx[j]];
    const double d[3] = {static_cast<double>(p.x - q.x), static_cast<double>(p.y - q.y), static_cast<double>(p.z - q.z)};
    for (int r = 0; r < 3; ++r) {
      sum[r] += d[r];
      for (int c = 0; c < 3; ++c) sum2[r][c] += d[r] * d[c];
    }
  }
  double C[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) C[r][c] = sum2[r][c] / found - (sum[r] / found) * (sum[c] / found);
  double nrm[3];
  smallest_eigenvector(C, nrm);
  // U diag(epsilon, 1, 1) U^T = I - (1 - epsilon) n n^T: only the normal matters.
  double R[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R[r][c] = (r == c ? 1.0 : 0.0) - (1.0 - epsilon) * nrm[r] * nrm[c];
  if (elevation_sigma > 0.0) {
    const double x = q.x, y = q.y, z = q.z;
    const double h = fmax(sqrt(x * x + y * y), 1e-6);
    const double v[3] = {-z * x / h, -z * y / h, h};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R[r][c] += elevation_sigma * elevation_sigma * v[r] * v[c];
  }
  out[0] = static_cast<float>(R[0][0]);
  out[1] = static_cast<float>(R[0][1]);
  out[2] = static_cast<float>(R[0][2]);
  out[3] = static_cast<float>(R[1][1]);
  out[4] = static_cast<float>(R[1][2]);
  out[5] = static_cast<float>(R[2][2]);
}

// xyz -> (x, y, z, 0): a point is one aligned 16-byte load on the device.
std::vector<float> padded_means(const float* xyz, uint32_t n) {
  std::vector<float> means(4 * static_cast<size_t>(n), 0.f);
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) means[4 * i + k] = xyz[3 * i + k];
  return means;
}

uint32_t num_blocks(size_t n) { return static_cast<uint32_t>((n + kThreads - 1) / kThreads); }

}  // namespace

int device_count(const char** why) {
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess) {
    // Without a driver the runtime reports "insufficient driver": say what that usually means.
    if (why) *why = e == cudaErrorInsufficientDriver ? "no CUDA driver, or one older than CUDA 13" : cudaGetErrorString(e);
    cudaGetLastError();  // clear the sticky error for a later try
    return 0;
  }
  if (n == 0 && why) *why = "no CUDA device";
  return n;
}

void select_device(int index) {
  check(cudaSetDevice(index), "cudaSetDevice");
  // The stream-ordered pool where the device has one, keeping what is freed: by default every
  // drain would hand it back to the driver and the next registration allocate afresh.
  int pools = 0;
  check(cudaDeviceGetAttribute(&pools, cudaDevAttrMemoryPoolsSupported, index), "cudaDeviceGetAttribute");
  use_pool = pools != 0;
  if (!use_pool) return;
  cudaMemPool_t pool;
  check(cudaDeviceGetDefaultMemPool(&pool, index), "cudaDeviceGetDefaultMemPool");
  uint64_t keep = UINT64_MAX;
  check(cudaMemPoolSetAttribute(pool, cudaMemPoolAttrReleaseThreshold, &keep), "cudaMemPoolSetAttribute");
}

const char* device_name() {
  static thread_local cudaDeviceProp prop;
  int dev = 0;
  check(cudaGetDevice(&dev), "cudaGetDevice");
  check(cudaGetDeviceProperties(&prop, dev), "cudaGetDeviceProperties");
  return prop.name;
}

Cloud upload_cloud(const float* xyz, const float* cov6, uint32_t n) {
  const std::vector<float> means = padded_means(xyz, n);
  Cloud c;
  c.size = n;
  c.means = device_alloc<float>(means.size());
  c.covs = device_alloc<float>(6 * static_cast<size_t>(n));
  upload(c.means, means.data(), means.size());
  upload(c.covs, cov6, 6 * static_cast<size_t>(n));
  drain("upload_cloud");
  return c;
}

void free_cloud(Cloud& c) {
  device_free(c.means);
  device_free(c.covs);
  c.size = 0;
}

VoxelMap upload_voxel_map(const int32_t* coords, const float* xyz, const float* cov6, uint32_t n, float inv_resolution,
                          uint32_t max_slots) {
  VoxelMap m;
  m.num_voxels = n;
  m.inv_resolution = inv_resolution;
  const std::vector<float> means = padded_means(xyz, n);
  m.means = device_alloc<float>(means.size());
  m.covs = device_alloc<float>(6 * static_cast<size_t>(n));
  upload(m.means, means.data(), means.size());
  upload(m.covs, cov6, 6 * static_cast<size_t>(n));
  int32_t* d_coords = device_alloc<int32_t>(3 * static_cast<size_t>(n));
  int* d_failed = device_alloc<int>(1);
  try {
    upload(d_coords, coords, 3 * static_cast<size_t>(n));
    const uint32_t slots = grow_voxel_table(n, max_slots, [&](uint32_t capacity) {
      device_free(m.slots);
      m.slots = device_alloc<VoxelSlot>(capacity);
      m.mask = capacity - 1;
      check(cudaMemsetAsync(m.slots, 0xff, capacity * sizeof(VoxelSlot), stream()), "cudaMemset");  // index -1: empty
      check(cudaMemsetAsync(d_failed, 0, sizeof(int), stream()), "cudaMemset");
      if (n > 0) build_table_kernel<<<num_blocks(n), kThreads, 0, stream()>>>(m.slots, m.mask, d_coords, n, d_failed);
      int failed = 0;
      download(&failed, d_failed, 1, "build_table_kernel");
      return failed == 0;
    });
    if (slots == 0)
      throw Error("voxel table: " + std::to_string(n) + " voxels do not fit in " + std::to_string(max_slots) + " slots within " +
                  std::to_string(kMaxProbes) + " probes");
  } catch (...) {
    device_free(d_coords);
    device_free(d_failed);
    free_voxel_map(m);
    throw;
  }
  device_free(d_coords);
  device_free(d_failed);
  return m;
}

void free_voxel_map(VoxelMap& m) {
  device_free(m.slots);
  device_free(m.means);
  device_free(m.covs);
  m.num_voxels = 0;
}

Batch::~Batch() { release(); }

void Batch::release() {
  device_free(pairs_);
  device_free(block_pair_);
  device_free(block_begin_);
  device_free(pair_first_block_);
  device_free(voxel_of_point_);
  device_free(poses_);
  device_free(block_sums_);
  device_free(pair_sums_);
  num_pairs_ = num_points_ = num_blocks_ = 0;
  device_bytes_ = 0;
}

void Batch::set_pairs(const std::vector<Cloud>& sources, const std::vector<VoxelMap>& targets,
                      const std::vector<float>& robust_widths) {
  release();
  num_pairs_ = sources.size();
  std::vector<PairView> views(num_pairs_);
  std::vector<int32_t> block_pair;
  std::vector<uint32_t> block_begin, first_block(num_pairs_ + 1, 0);
  for (size_t f = 0; f < num_pairs_; ++f) {
    const float c = robust_widths[f];
    views[f] = {sources[f].means, sources[f].covs,      sources[f].size, static_cast<uint32_t>(num_points_),
                targets[f],       c > 0.f ? c * c : 0.f};
    first_block[f] = static_cast<uint32_t>(block_pair.size());
    for (uint32_t b = 0; b < num_blocks(sources[f].size); ++b) {
      block_pair.push_back(static_cast<int32_t>(f));
      block_begin.push_back(b * kThreads);
    }
    num_points_ += sources[f].size;
  }
  first_block[num_pairs_] = static_cast<uint32_t>(block_pair.size());
  num_blocks_ = block_pair.size();
  PairView* d_views = device_alloc<PairView>(num_pairs_);
  pairs_ = d_views;
  upload(d_views, views.data(), num_pairs_);
  block_pair_ = device_alloc<int32_t>(num_blocks_);
  block_begin_ = device_alloc<uint32_t>(num_blocks_);
  pair_first_block_ = device_alloc<uint32_t>(num_pairs_ + 1);
  upload(block_pair_, block_pair.data(), num_blocks_);
  upload(block_begin_, block_begin.data(), num_blocks_);
  upload(pair_first_block_, first_block.data(), num_pairs_ + 1);
  voxel_of_point_ = device_alloc<int32_t>(num_points_);
  poses_ = device_alloc<float>(12 * num_pairs_);
  block_sums_ = device_alloc<float>(kSums * num_blocks_);
  pair_sums_ = device_alloc<double>(kSums * num_pairs_);
  drain("set_pairs");
  device_bytes_ = num_pairs_ * (sizeof(PairView) + sizeof(uint32_t) + 12 * sizeof(float) + kSums * sizeof(double)) +
                  num_blocks_ * (sizeof(int32_t) + sizeof(uint32_t) + kSums * sizeof(float)) + num_points_ * sizeof(int32_t);
}

void Batch::linearize(const float* T, double* sums) {
  if (num_pairs_ == 0) return;
  upload(poses_, T, 12 * num_pairs_);
  const auto* pairs = static_cast<const PairView*>(pairs_);
  if (num_blocks_ > 0)
    linearize_kernel<<<static_cast<uint32_t>(num_blocks_), kThreads, 0, stream()>>>(pairs, block_pair_, block_begin_, poses_,
                                                                                    voxel_of_point_, block_sums_);
  pair_sums_kernel<<<static_cast<uint32_t>(num_pairs_), 32, 0, stream()>>>(pair_first_block_, block_sums_, kSums, pair_sums_);
  download(sums, pair_sums_, kSums * num_pairs_, "linearize");
}

void Batch::trial_errors(const float* T, double* errors) {
  if (num_pairs_ == 0) return;
  upload(poses_, T, 12 * num_pairs_);
  const auto* pairs = static_cast<const PairView*>(pairs_);
  if (num_blocks_ > 0)
    trial_kernel<<<static_cast<uint32_t>(num_blocks_), kThreads, 0, stream()>>>(pairs, block_pair_, block_begin_, poses_,
                                                                                voxel_of_point_, block_sums_);
  pair_sums_kernel<<<static_cast<uint32_t>(num_pairs_), 32, 0, stream()>>>(pair_first_block_, block_sums_, 2, pair_sums_);
  download(errors, pair_sums_, 2 * num_pairs_, "trial_errors");
}

OverlapScratch::~OverlapScratch() {
  device_free(targets);
  device_free(poses);
  device_free(block_hits);
}

void overlap_counts(const Cloud& source, const std::vector<VoxelMap>& targets, const float* T, uint32_t* hits,
                    OverlapScratch& scratch) {
  const size_t nt = targets.size();
  for (size_t k = 0; k < nt; ++k) hits[k] = 0;
  if (nt == 0 || source.size == 0) return;
  const uint32_t per_target = num_blocks(source.size);
  const size_t blocks = static_cast<size_t>(per_target) * nt;
  if (nt > scratch.target_capacity) {
    device_free(scratch.targets);
    device_free(scratch.poses);
    scratch.targets = device_alloc<VoxelMap>(nt);
    scratch.poses = device_alloc<float>(12 * nt);
    scratch.target_capacity = nt;
  }
  if (blocks > scratch.block_capacity) {
    device_free(scratch.block_hits);
    scratch.block_hits = device_alloc<uint32_t>(blocks);
    scratch.block_capacity = blocks;
  }
  upload(scratch.targets, targets.data(), nt);
  upload(scratch.poses, T, 12 * nt);
  overlap_kernel<<<static_cast<uint32_t>(blocks), kThreads, 0, stream()>>>(source.means, source.size, scratch.targets,
                                                                           scratch.poses, per_target, scratch.block_hits);
  std::vector<uint32_t> block_hits(blocks);
  download(block_hits.data(), scratch.block_hits, blocks, "overlap");
  for (size_t b = 0; b < blocks; ++b) hits[b / per_target] += block_hits[b];
}

CovarianceScratch::~CovarianceScratch() {
  device_free(means);
  device_free(covs);
}

void point_covariances(const float* xyz, uint32_t n, int k, double epsilon, double elevation_sigma, float* cov6,
                       CovarianceScratch& scratch) {
  if (k < 1 || k > kMaxNeighbors) throw Error("point_covariances: k must be in [1, " + std::to_string(kMaxNeighbors) + "]");
  if (n == 0) return;
  if (n > scratch.capacity) {
    device_free(scratch.means);
    device_free(scratch.covs);
    scratch.means = device_alloc<float>(4 * static_cast<size_t>(n));
    scratch.covs = device_alloc<float>(6 * static_cast<size_t>(n));
    scratch.capacity = n;
  }
  const std::vector<float> means = padded_means(xyz, n);
  upload(scratch.means, means.data(), means.size());
  covariance_kernel<<<num_blocks(n), kThreads, 0, stream()>>>(reinterpret_cast<const float4*>(scratch.means), n, k, epsilon,
                                                              elevation_sigma, scratch.covs);
  download(cov6, scratch.covs, 6 * static_cast<size_t>(n), "covariances");
}

}  // namespace gcmap::cuda::device
