#pragma once
// A procedural urban world for ray casting: hilly ground, buildings, walls, parked cars, poles and
// trees, indexed by a uniform 2D grid.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace gcmap::sim {

struct Box {
  Eigen::Vector3f min, max;
  float reflectivity;
};
struct Cylinder {  // vertical
  Eigen::Vector2f center;
  float radius, z0, z1, reflectivity;
};
struct Sphere {
  Eigen::Vector3f center;
  float radius, reflectivity;
};

struct Hit {
  float range = 0.f;
  float reflectivity = 0.f;
};

class World {
 public:
  // Streets run along every grid line x = k * block, y = k * block inside [lo, hi] (in blocks).
  World(uint64_t seed, float block, Eigen::Vector2i lo, Eigen::Vector2i hi, bool feature_poor);

  float ground_height(float x, float y) const;
  Eigen::Vector2f ground_gradient(float x, float y) const;
  bool raycast(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float max_range, Hit& hit) const;

  size_t num_objects() const { return boxes_.size() + cylinders_.size() + spheres_.size(); }

 private:
  void add_box(const Box& b);
  void add_cylinder(const Cylinder& c);
  void add_sphere(const Sphere& s);
  void index(int kind, int id, Eigen::Vector2f lo, Eigen::Vector2f hi);
  bool ground_hit(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t_max, float& t) const;

  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  std::vector<Sphere> spheres_;
  // Grid cells hold (kind << 28 | id) entries, in CSR form after construction.
  float cell_ = 4.f;
  Eigen::Vector2f origin_;
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<uint32_t>> build_cells_;
  std::vector<uint32_t> cell_start_, cell_items_;
};

}  // namespace gcmap::sim
