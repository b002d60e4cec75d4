#pragma once
#include <nanoflann.hpp>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace gcmap {

// k-nearest-neighbour search over float points (nanoflann; the points must outlive it).
class KdTree {
 public:
  explicit KdTree(const std::vector<Eigen::Vector3f>& points)
      : adaptor_{points}, index_(3, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {
    index_.buildIndex();
  }
  KdTree(std::vector<Eigen::Vector3f>&&) = delete;  // it keeps a reference: a temporary would dangle

  // Writes up to k neighbours (sorted by distance) and returns how many were found.
  size_t knn(const Eigen::Vector3f& query, size_t k, uint32_t* indices, float* sq_dists) const {
    if (adaptor_.points.empty() || k == 0) return 0;  // nanoflann answers an empty tree with garbage
    nanoflann::KNNResultSet<float, uint32_t> result(k);
    result.init(indices, sq_dists);
    index_.findNeighbors(result, query.data(), nanoflann::SearchParams(32, 0.0f, true));
    return result.size();
  }

 private:
  struct Adaptor {
    const std::vector<Eigen::Vector3f>& points;
    size_t kdtree_get_point_count() const { return points.size(); }
    float kdtree_get_pt(size_t i, size_t dim) const { return points[i][dim]; }
    template <class BBox>
    bool kdtree_get_bbox(BBox&) const {
      return false;
    }
  };
  using Index = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Adaptor>, Adaptor, 3, uint32_t>;

  Adaptor adaptor_;
  Index index_;
};

}  // namespace gcmap
