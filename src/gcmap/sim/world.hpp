#pragma once
// A procedural world for ray casting: hilly ground and static primitives (boxes, oriented boxes,
// vertical cylinders, spheres), indexed by a uniform 2D grid. The scene builders (builders.hpp)
// fill it.
#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <vector>

namespace gcmap::sim {

// SemanticKITTI classes (lower 16 bits of a .label entry).
enum Label : uint16_t {
  kUnlabeled = 0,
  kOutlier = 1,
  kCar = 10,
  kRoad = 40,
  kSidewalk = 48,
  kBuilding = 50,
  kFence = 51,
  kVegetation = 70,
  kTrunk = 71,
  kTerrain = 72,
  kPole = 80,
  kMovingCar = 252,
  kMovingBicyclist = 253,
  kMovingPerson = 254,
  kMovingTruck = 258,
};

// A box exists for times in [t_begin, t_end) (parked cars that leave). A porous sphere (canopies,
// bushes) lets a ray through with that probability and otherwise returns from a random depth inside.
struct Box {
  Eigen::Vector3f min, max;
  float reflectivity;
  uint16_t label = kUnlabeled;
  float t_begin = -std::numeric_limits<float>::infinity(), t_end = std::numeric_limits<float>::infinity();
};
struct OrientedBox {  // rotated by yaw about z
  Eigen::Vector3f center, half;
  float yaw, reflectivity;
  uint16_t label = kUnlabeled;
};
struct Cylinder {  // vertical
  Eigen::Vector2f center;
  float radius, z0, z1, reflectivity;
  uint16_t label = kUnlabeled;
};
struct Sphere {
  Eigen::Vector3f center;
  float radius, reflectivity;
  uint16_t label = kUnlabeled;
  float porosity = 0.f;
};

// Ground height: a sum of two sines per axis. The default is the gentle terrain of the original
// city scenarios.
struct Terrain {
  float amp_x = 1.6f, len_x = 110.f, amp_y = 1.1f, len_y = 75.f;
  uint16_t label = kRoad;
  float reflectivity = 0.1f;
  int trace_steps = 64;  // sphere-tracing iterations; steep terrain needs more to reach far
};

struct Hit {
  float range = 0.f;
  float reflectivity = 0.f;
  uint16_t label = kUnlabeled;
  float cos_incidence = 1.f;  // |cos| of the angle between the ray and the surface normal
};

// Per-ray context: the time of the firing (for primitives that come and go) and a random key (for
// porous primitives), so a ray's outcome is a pure function of its inputs.
struct RayContext {
  float time = 0.f;
  uint64_t key = 0;
};

// Slab test of an axis-aligned box; false when the origin is inside. Shared with the traffic.
bool intersect_box(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, const Eigen::Vector3f& o, const Eigen::Vector3f& inv_dir,
                   float& t, int& axis);

class World {
 public:
  // Covers [lo, hi] (metres) in x and y; primitives outside are clipped from the index.
  World(const Terrain& terrain, Eigen::Vector2f lo, Eigen::Vector2f hi);

  float ground_height(float x, float y) const;
  Eigen::Vector2f ground_gradient(float x, float y) const;
  bool raycast(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float max_range, Hit& hit,
               const RayContext& ctx = {}) const;
  // Ground truth for maps: whether a primitive that stands for the whole drive (not porous, not a
  // parked car that comes or goes) occupies any height in [z0, z1] above map point (x, y).
  bool column_solid(float x, float y, float z0, float z1) const;

  void add_box(const Box& b);
  void add_oriented_box(const OrientedBox& b);
  void add_cylinder(const Cylinder& c);
  void add_sphere(const Sphere& s);
  // Builds the cell index; call once after the last add.
  void finalize();
  // Mutable access for builders that edit primitives after adding them (parked cars leaving).
  std::vector<Box>& boxes() { return boxes_; }
  std::vector<Sphere>& spheres() { return spheres_; }

 private:
  void index(int kind, int id, Eigen::Vector2f lo, Eigen::Vector2f hi);
  bool ground_hit(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t_max, float& t) const;
  bool hit_item(uint32_t item, const Eigen::Vector3f& o, const Eigen::Vector3f& d, const Eigen::Vector3f& inv,
                const RayContext& ctx, float& t, Hit& h) const;
  bool item_in_column(uint32_t item, const Eigen::Vector2f& p, float z0, float z1) const;

  Terrain terrain_;
  float max_grad_ = 0.f;
  std::vector<Box> boxes_;
  std::vector<OrientedBox> oboxes_;
  std::vector<Cylinder> cylinders_;
  std::vector<Sphere> spheres_;
  // Grid cells hold (kind << 28 | id) entries, in CSR form after finalize().
  float cell_ = 4.f;
  Eigen::Vector2f origin_;
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<uint32_t>> build_cells_;
  std::vector<uint32_t> cell_start_, cell_items_;
};

}  // namespace gcmap::sim
