#include "ingest/bucket_split.h"

#include <algorithm>
#include <limits>
#include <utility>

namespace relief::ingest {

namespace {

constexpr std::uint32_t kNoPart = std::numeric_limits<std::uint32_t>::max();

// A load's records on their way to its file, written as one block when the
// buffer fills (`runs`: chunk key and record count, in record order).
struct Pending {
  std::vector<std::uint8_t> bytes;
  std::vector<std::pair<ChunkKey, std::uint32_t>> runs;
  std::uint32_t points = 0;
};

}  // namespace

std::uint32_t BucketSplit::leaf(const std::vector<Node>& nodes, std::uint32_t root, const Vec3d& p) {
  std::uint32_t n = root;
  while (nodes[n].first_child >= 0) {
    const Node& d = nodes[n];
    const Octants octants{d.origin, d.edge / 2};
    n = static_cast<std::uint32_t>(d.first_child + octants.of(p, octants.mid()));
  }
  return n;
}

Result<BucketSplit> BucketSplit::create(const BucketFiles& files, std::uint32_t bucket, const ArchiveGrid& grid,
                                        const BucketSplitOptions& o, AlignedBuffer& buf,
                                        const std::function<void()>& tick, const std::atomic<bool>* cancel) {
  std::uint64_t seen = 0;
  const auto progress = [&](std::uint32_t n) -> Status {
    const std::uint64_t before = seen;
    seen += n;
    if ((before >> 16) == (seen >> 16)) return Status::ok();
    if (tick) tick();
    if (cancel != nullptr && cancel->load()) return io_error("interrupted");
    return Status::ok();
  };
  std::vector<Node> nodes;
  std::unordered_map<ChunkKey, std::uint32_t, ChunkKeyHash> roots;
  int passes = 0;
  // Pass 1: the points of every chunk.
  RELIEF_RETURN_IF_ERROR(files.scan(bucket, buf, [&](const ChunkKey& key, const Vec3d&, const std::uint8_t*,
                                                     std::uint32_t n) -> Status {
    const auto [it, inserted] = roots.try_emplace(key, static_cast<std::uint32_t>(nodes.size()));
    if (inserted) {
      Node root;
      root.origin = grid.chunk_box(key).min;
      root.edge = grid.chunk_edge;
      nodes.push_back(root);
    }
    nodes[it->second].count += n;
    return progress(n);
  }));
  ++passes;
  // Then the octants of every part still too large, two levels per pass:
  // each such part gets its 8 children and their 64 children, counted in one
  // pass; a child that turns out small enough drops its own again.
  const std::size_t record = files.record_bytes();
  const auto add_children = [&](std::uint32_t i) {
    const Node parent = nodes[i];
    const Octants octants{parent.origin, parent.edge / 2};
    const Vec3d mid = octants.mid();
    nodes[i].first_child = static_cast<std::int32_t>(nodes.size());
    for (int c = 0; c < 8; ++c) {
      Node child;
      child.origin = octants.origin_of(c, mid);
      child.edge = octants.half;
      child.depth = static_cast<std::uint8_t>(parent.depth + 1);
      Octants::sub_of(parent.sub, c, child.sub);
      child.parent = static_cast<std::int32_t>(i);
      nodes.push_back(child);
    }
  };
  for (;;) {
    const auto first_new = static_cast<std::uint32_t>(nodes.size());
    for (std::uint32_t i = 0; i < first_new; ++i) {
      if (nodes[i].first_child >= 0 || nodes[i].count <= o.split_points || nodes[i].depth >= kMaxSplitDepth) continue;
      add_children(i);
      const auto first_child = static_cast<std::uint32_t>(nodes[i].first_child);
      for (std::uint32_t c = first_child; c < first_child + 8; ++c) {
        if (nodes[c].depth < kMaxSplitDepth) add_children(c);
      }
    }
    if (nodes.size() == first_new) break;
    const Status counted = files.scan(bucket, buf, [&](const ChunkKey& key, const Vec3d& lo, const std::uint8_t* r,
                                                       std::uint32_t n) -> Status {
      const auto it = roots.find(key);
      if (it == roots.end()) return corrupt_data("temporary bucket file changed between passes");
      for (std::uint32_t i = 0; i < n; ++i, r += record) {
        const std::uint32_t l = leaf(nodes, it->second, files.position(lo, r));
        if (l < first_new) continue;
        ++nodes[l].count;
        const auto up = static_cast<std::uint32_t>(nodes[l].parent);
        if (up >= first_new) ++nodes[up].count;
      }
      return progress(n);
    });
    RELIEF_RETURN_IF_ERROR(counted);
    ++passes;
    for (auto c = first_new; c < nodes.size(); ++c) {
      Node& child = nodes[c];
      if (child.first_child < 0 || child.count > o.split_points) continue;
      for (int g = 0; g < 8; ++g) nodes[static_cast<std::size_t>(child.first_child + g)].count = 0;
      child.first_child = -1;
    }
  }
  // The parts, chunk by chunk in key order and depth first, packed whole into
  // loads.
  std::vector<std::pair<ChunkKey, std::uint32_t>> ordered(roots.begin(), roots.end());
  std::sort(ordered.begin(), ordered.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Part> parts;
  std::vector<std::uint32_t> load_first = {0};
  std::vector<std::uint32_t> load_of_part;
  std::uint64_t in_load = 0;
  for (Node& n : nodes) n.part = kNoPart;
  std::vector<std::uint32_t> stack;
  for (const auto& [key, root] : ordered) {
    stack.assign(1, root);
    while (!stack.empty()) {
      const std::uint32_t n = stack.back();
      stack.pop_back();
      if (nodes[n].first_child >= 0) {
        for (int c = 7; c >= 0; --c) stack.push_back(static_cast<std::uint32_t>(nodes[n].first_child + c));
        continue;
      }
      if (nodes[n].count == 0) continue;
      if (in_load > 0 && in_load + nodes[n].count > o.load_points) {
        load_first.push_back(static_cast<std::uint32_t>(parts.size()));
        in_load = 0;
      }
      in_load += nodes[n].count;
      nodes[n].part = static_cast<std::uint32_t>(parts.size());
      load_of_part.push_back(static_cast<std::uint32_t>(load_first.size() - 1));
      parts.push_back({key, n});
    }
  }
  load_first.push_back(static_cast<std::uint32_t>(parts.size()));
  const auto loads = static_cast<std::uint32_t>(load_first.size() - 1);
  if (loads == 0) return internal_error("splitting an empty bucket");

  // The last pass: every record, as it is, to its load's file.
  RELIEF_ASSIGN_OR_RETURN(BucketFiles load_files,
                          BucketFiles::create(o.tmp_parent, loads, grid, files.colors(), files.intensity(),
                                              o.staging_bytes / 2, files.las_attributes(), files.extra_bytes_size()));
  load_files.set_explicit_buckets();
  const std::size_t flush_at = std::clamp<std::size_t>(o.staging_bytes / 2 / loads, std::size_t{64} << 10,
                                                       std::size_t{8} << 20);
  std::vector<Pending> pending(loads);
  const Status routed = files.scan(bucket, buf, [&](const ChunkKey& key, const Vec3d& lo, const std::uint8_t* r,
                                                     std::uint32_t n) -> Status {
    const auto it = roots.find(key);
    if (it == roots.end()) return corrupt_data("temporary bucket file changed between passes");
    for (std::uint32_t i = 0; i < n; ++i, r += record) {
      const std::uint32_t part = nodes[leaf(nodes, it->second, files.position(lo, r))].part;
      if (part == kNoPart) return corrupt_data("temporary bucket file changed between passes");
      const std::uint32_t load = load_of_part[part];
      Pending& q = pending[load];
      if (q.runs.empty() || !(q.runs.back().first == key)) q.runs.emplace_back(key, 0);
      ++q.runs.back().second;
      q.bytes.insert(q.bytes.end(), r, r + record);
      ++q.points;
      if (q.bytes.size() >= flush_at) {
        RELIEF_RETURN_IF_ERROR(load_files.append_block(load, q.runs, q.bytes.data(), q.points));
        q.bytes.clear();
        q.runs.clear();
        q.points = 0;
      }
    }
    return progress(n);
  });
  RELIEF_RETURN_IF_ERROR(routed);
  ++passes;
  for (std::uint32_t load = 0; load < loads; ++load) {
    Pending& q = pending[load];
    RELIEF_RETURN_IF_ERROR(load_files.append_block(load, q.runs, q.bytes.data(), q.points));
    q = Pending();
  }
  RELIEF_RETURN_IF_ERROR(load_files.finish_writing());

  BucketSplit split(std::move(load_files));
  split.nodes_ = std::move(nodes);
  split.roots_ = std::move(roots);
  split.parts_ = std::move(parts);
  split.load_first_part_ = std::move(load_first);
  split.passes_ = passes;
  return split;
}

Result<std::vector<ChunkTask>> BucketSplit::read_load(std::uint32_t load, PointCloud& points, Grouping& g,
                                                      AlignedBuffer& buf) {
  std::uint64_t offset = 0;
  RELIEF_RETURN_IF_ERROR(loads_.read_slice(load, &offset, ~std::uint64_t{0}, points, g, buf));
  const std::uint32_t first = load_first_part_[load];
  const std::uint32_t count = load_first_part_[load + 1] - first;
  const auto damaged = [&](const std::string& what) {
    return corrupt_data(loads_.directory() + ": temporary load " + std::to_string(load) + " damaged: " + what);
  };
  // Each point's part (local number), then the points grouped by part.
  std::vector<std::uint32_t> local(points.size());
  std::vector<std::uint64_t> start(std::size_t{count} + 1, 0);
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto it = roots_.find(g.keys[g.ids[k]]);
    if (it == roots_.end()) return damaged("a point of a chunk it does not hold");
    const std::uint32_t part = nodes_[leaf(nodes_, it->second, points.positions[k])].part;
    if (part < first || part - first >= count) return damaged("a point of a part it does not hold");
    local[k] = part - first;
    ++start[local[k] + 1];
  }
  for (std::uint32_t i = 0; i < count; ++i) {
    const std::uint64_t expected = nodes_[parts_[first + i].node].count;
    if (start[i + 1] != expected) {
      return damaged(std::to_string(start[i + 1]) + " points of a part that held " + std::to_string(expected));
    }
    start[i + 1] += start[i];
  }
  g.order.resize(points.size());
  std::vector<std::uint64_t> fill(start.begin(), start.end() - 1);
  for (std::size_t k = 0; k < points.size(); ++k) g.order[fill[local[k]]++] = static_cast<std::uint32_t>(k);
  std::vector<ChunkTask> tasks(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    const Node& n = nodes_[parts_[first + i].node];
    ChunkTask& t = tasks[i];
    t.key = parts_[first + i].key;
    t.split_depth = n.depth;
    for (int a = 0; a < 3; ++a) t.sub[a] = n.sub[a];
    t.source = &points;
    t.index = g.order.data() + start[i];
    t.count = static_cast<std::size_t>(start[i + 1] - start[i]);
  }
  std::stable_sort(tasks.begin(), tasks.end(),
                   [](const ChunkTask& a, const ChunkTask& b) { return a.count > b.count; });
  return tasks;
}

}  // namespace relief::ingest
