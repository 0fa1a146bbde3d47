#include "synth/fisheye_subdivision.h"

#include <algorithm>
#include <array>
#include <limits>

#include "core/parallel.h"

namespace hmc {
namespace {

// A vertex of the subdivision: camera-frame point, its projection, and its
// row in the output (>= 0: a mesh vertex; < 0: -(k + 1), the k-th new one).
struct SubVertex {
  Vec3 p;
  Vec2 s;
  int ref;
};

struct ChunkOut {
  std::vector<Eigen::Vector3d> new_rows;
  std::vector<std::array<int, 3>> tris;
  std::vector<int> face;
  int64_t input = 0;
  int64_t split = 0;
  double max_error = 0;
};

class Subdivider {
 public:
  Subdivider(const FastFisheye& camera, double tolerance, ChunkOut* out)
      : camera_(camera), tolerance_(tolerance), out_(out) {}

  // Midpoint sagitta of edge (a, b); depends on the edge alone (symmetric in
  // a and b), so both triangles sharing an edge make the same decision.
  // Returns false if the midpoint does not project.
  bool EdgeError(const SubVertex& a, const SubVertex& b, SubVertex* mid,
                 double* error) const {
    mid->p = 0.5 * (a.p + b.p);
    if (!camera_.Project(mid->p, &mid->s)) return false;
    *error = (mid->s - 0.5 * (a.s + b.s)).norm();
    return true;
  }

  // Emits triangle (a, b, c) of mesh face `face`, split where needed.
  void Emit(const SubVertex& a, const SubVertex& b, const SubVertex& c, int face,
            int depth) {
    SubVertex m[3];
    double err[3];
    const SubVertex* v[3] = {&a, &b, &c};
    bool split[3];
    int num_split = 0;
    for (int e = 0; e < 3; ++e) {
      const SubVertex& p = *v[e];
      const SubVertex& q = *v[(e + 1) % 3];
      if (!EdgeError(p, q, &m[e], &err[e])) return;
      // Edges shorter than a quarter pixel are not split further: their
      // error is already far below any tolerance in practice.
      split[e] = err[e] > tolerance_ && (p.s - q.s).norm() > 0.25 && depth < kMaxDepth;
      num_split += split[e];
    }
    // Far off the image (beyond it by its sagittas and one image size; a
    // real lens never projects there): never split, so the work is bounded
    // by the image size whatever the lens (docs/reliability.md).
    const double size = camera_.width + camera_.height;
    const double pad = std::min(std::max({err[0], err[1], err[2]}), size) + size;
    if (std::max({a.s.x(), b.s.x(), c.s.x()}) < -pad || std::max({a.s.y(), b.s.y(), c.s.y()}) < -pad ||
        std::min({a.s.x(), b.s.x(), c.s.x()}) > camera_.width + pad ||
        std::min({a.s.y(), b.s.y(), c.s.y()}) > camera_.height + pad) {
      out_->tris.push_back({a.ref, b.ref, c.ref});
      out_->face.push_back(face);
      return;
    }
    if (num_split == 0) {
      out_->tris.push_back({a.ref, b.ref, c.ref});
      out_->face.push_back(face);
      out_->max_error = std::max({out_->max_error, err[0], err[1], err[2]});
      return;
    }
    if (depth == 0) ++out_->split;
    for (int e = 0; e < 3; ++e) {
      if (split[e]) m[e].ref = AddVertex(m[e]);
    }
    if (num_split == 3) {
      Emit(a, m[0], m[2], face, depth + 1);
      Emit(m[0], b, m[1], face, depth + 1);
      Emit(m[2], m[1], c, face, depth + 1);
      Emit(m[0], m[1], m[2], face, depth + 1);
      return;
    }
    // Rotate so that edge 0 (v0 v1) is split and, for two splits, edge 1 too.
    int r = 0;
    if (num_split == 1) {
      while (!split[r]) ++r;
    } else {
      while (split[r]) ++r;  // r: the unsplit edge
      r = (r + 1) % 3;
    }
    const SubVertex& v0 = *v[r];
    const SubVertex& v1 = *v[(r + 1) % 3];
    const SubVertex& v2 = *v[(r + 2) % 3];
    const SubVertex& m01 = m[r];
    if (num_split == 1) {
      Emit(v0, m01, v2, face, depth + 1);
      Emit(m01, v1, v2, face, depth + 1);
    } else {
      const SubVertex& m12 = m[(r + 1) % 3];
      Emit(m01, v1, m12, face, depth + 1);
      Emit(v0, m01, m12, face, depth + 1);
      Emit(v0, m12, v2, face, depth + 1);
    }
  }

 private:
  static constexpr int kMaxDepth = 10;
  int AddVertex(const SubVertex& v) {
    out_->new_rows.emplace_back(v.s.x(), v.s.y(), v.p.norm());
    return -static_cast<int>(out_->new_rows.size());
  }
  const FastFisheye& camera_;
  double tolerance_;
  ChunkOut* out_;
};

}  // namespace

FisheyeTriangles SubdivideForFisheye(const FisheyeCamera& camera, const MatX3d& X_cam,
                                     const MatX3i& F, double max_edge_error_px) {
  const FastFisheye fast(camera);
  const int num_vertices = static_cast<int>(X_cam.rows());
  FisheyeTriangles out;
  out.screen.resize(num_vertices, 3);
  std::vector<char> ok(num_vertices, 0);
  ParallelFor(
      0, num_vertices,
      [&](int64_t v) {
        Vec2 s;
        const Vec3 p = X_cam.row(v).transpose();
        if (fast.Project(p, &s)) {
          out.screen.row(v) << s.x(), s.y(), p.norm();
          ok[v] = 1;
        } else {
          out.screen.row(v).setConstant(std::numeric_limits<double>::quiet_NaN());
        }
      },
      1024);
  const int num_faces = static_cast<int>(F.rows());
  constexpr int kChunk = 2048;
  const int num_chunks = (num_faces + kChunk - 1) / kChunk;
  std::vector<ChunkOut> chunks(num_chunks);
  ParallelFor(0, num_chunks, [&](int64_t chunk) {
    ChunkOut& co = chunks[chunk];
    Subdivider subdivider(fast, max_edge_error_px, &co);
    const int end = std::min(num_faces, static_cast<int>((chunk + 1) * kChunk));
    for (int f = static_cast<int>(chunk) * kChunk; f < end; ++f) {
      SubVertex c[3];
      bool valid = true;
      for (int i = 0; i < 3; ++i) {
        const int v = F(f, i);
        if (v < 0 || v >= num_vertices || !ok[v]) {
          valid = false;
          break;
        }
        c[i] = {X_cam.row(v).transpose(), out.screen.row(v).head<2>().transpose(), v};
      }
      if (!valid) continue;
      // Back faces (counter-clockwise seen from outside, camera at origin).
      const Vec3 n = (c[1].p - c[0].p).cross(c[2].p - c[0].p);
      if (!(n.dot(-c[0].p) > 0)) continue;
      ++co.input;
      subdivider.Emit(c[0], c[1], c[2], f, 0);
    }
  });
  // Concatenate in chunk order: the same result whatever the schedule.
  int64_t num_new = 0, num_tris = 0;
  for (const ChunkOut& co : chunks) {
    num_new += static_cast<int64_t>(co.new_rows.size());
    num_tris += static_cast<int64_t>(co.tris.size());
  }
  out.screen.conservativeResize(num_vertices + num_new, 3);
  out.F.resize(num_tris, 3);
  out.face.resize(num_tris);
  int64_t row = num_vertices, tri = 0;
  for (const ChunkOut& co : chunks) {
    const int64_t base = row;
    for (const Eigen::Vector3d& r : co.new_rows) out.screen.row(row++) = r.transpose();
    for (size_t t = 0; t < co.tris.size(); ++t, ++tri) {
      for (int i = 0; i < 3; ++i) {
        const int ref = co.tris[t][i];
        out.F(tri, i) = ref >= 0 ? ref : static_cast<int>(base + (-ref - 1));
      }
      out.face[tri] = co.face[t];
    }
    out.stats.input_triangles += co.input;
    out.stats.split_triangles += co.split;
    out.stats.max_edge_error_px = std::max(out.stats.max_edge_error_px, co.max_error);
  }
  out.stats.output_triangles = num_tris;
  return out;
}

}  // namespace hmc
