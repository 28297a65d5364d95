// Ablation of the pipeline's options on seeded synthetic scenes with exact ground truth.
// Usage: binpose_bench_ablation MODEL_MESH|builtin:cap [SCENES=10] [COPIES=4]
// Each scene: COPIES copies of the model at random poses on a grid (some touching), rendered
// by a z-buffer with 0.1 mm depth noise. A detection is correct within 0.1 x diameter of a copy's
// centroid; errors are over the correct ones.
#include <binpose/detector.hpp>
#include <binpose/io.hpp>
#include <binpose/shapes.hpp>

#include "stage_settings.hpp"

#include "../tests/synthetic.hpp"

#include <algorithm>
#include <cstdio>
#include <string>

using namespace binpose;

namespace {

struct Variant {
  const char* name;
  StageSettings params;
};

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s MODEL_MESH [SCENES] [COPIES]\n", argv[0]);
    return 2;
  }
  const int scenes = argc > 2 ? std::stoi(argv[2]) : 10, copies = argc > 3 ? std::stoi(argv[3]) : 4;
  const ModelFile file = readModelOrBuiltin(argv[1]);
  if (!file.is_mesh) {
    std::fprintf(stderr, "%s: the ablation simulates scenes and needs a mesh\n", argv[1]);
    return 2;
  }
  const Mesh& mesh = file.mesh;
  const OrientedModel model = prepareModel(mesh, ModelParams{});
  const ModelDatabase db = ModelDatabase::build(model, defaultQuantization(model.diameter));
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : model.points) centroid += p;
  centroid /= float(model.points.size());

  const auto stages = [&](const DetectionParams& user) { return stageSettings(scaledToModel(user, model.diameter), model.diameter); };
  std::vector<Variant> variants;
  StageSettings p = stages(thesisPreset());
  variants.push_back({"thesis (random, no refine, no verify)", p});
  p.subsampling = Subsampling::Voxel;
  variants.push_back({"thesis + voxel sub-sampling", p});
  p.verify = true;
  variants.push_back({"thesis + voxel + verify", p});
  p.refine = true;
  variants.push_back({"thesis + voxel + verify + ICP", p});
  variants.push_back({"default (local votes, planes, symmetry, ...)", stages(defaultPreset())});
  p = stages(defaultPreset());
  p.retry_all_voters = false;
  variants.push_back({"default without the second pass", p});
  p = stages(defaultPreset());
  p.mild_outlier_candidates = 0;
  variants.push_back({"default, eq. 11's upper outliers alone", p});

  std::printf("model %s, %.1f mm; %d scenes x %d copies\n", argv[1], model.diameter, scenes, copies);
  std::printf("%-40s %7s %6s %9s %9s %9s\n", "variant", "recall", "false", "cent mm", "angle deg", "ms/scene");
  for (const Variant& v : variants) {
    const Detector detector(db, v.params);
    int correct = 0, wrong = 0;
    std::vector<double> cent, ang, ms;
    for (int s = 0; s < scenes; ++s) {
      Rng rng(1000 + s);
      std::vector<Pose> truth;
      const float spacing = 0.9f * model.diameter;  // close enough that copies occlude each other
      for (int c = 0; c < copies; ++c)
        truth.push_back(test::randomPose(rng, Vec3(spacing * float(c % 2), spacing * float(c / 2), 600.0f)));
      test::SyntheticView view;
      view.seed = 77 + s;
      const PointCloud scan = test::renderCopies(mesh, truth, view, [](std::size_t, const Vec3&) { return true; });
      const DetectionResult r = detector.detect(scan);
      ms.push_back(r.timing.total_ms);
      std::vector<char> used(truth.size(), 0);
      for (const Detection& d : r.detections) {
        int best = -1;
        float best_d = 0.1f * model.diameter;
        for (std::size_t t = 0; t < truth.size(); ++t) {
          const float e = (d.pose * centroid - truth[t] * centroid).norm();
          if (!used[t] && e < best_d) { best = int(t); best_d = e; }
        }
        if (best < 0) {
          ++wrong;
          continue;
        }
        used[best] = 1;
        ++correct;
        cent.push_back(best_d);
        ang.push_back(Eigen::AngleAxisf(d.pose.linear().transpose() * truth[best].linear()).angle() * 180.0 / M_PI);
      }
    }
    std::printf("%-40s %6.1f%% %6d %9.3f %9.3f %9.0f\n", v.name, 100.0 * correct / (scenes * copies), wrong, median(cent),
                median(ang), median(ms));
  }
  std::printf("(errors and time: medians)\n");
  return 0;
}
