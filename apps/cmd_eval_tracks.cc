// `hmc eval-tracks --tracks tracks_2d.csv --truth SHOT/dots_2d.csv [--json FILE]`:
// how `hmc track`'s output compares with a synthetic shot's ground truth
// (tracking/track_eval.h): accuracy of full dots, recall of full and partial
// dots, wrong names, rows on hidden dots; with a shot that has the `whole`
// and `cos` columns, recall and centre error of whole dots per view-cosine
// bin.
#include <memory>
#include <string>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/file_util.h"
#include "core/tracks_2d.h"
#include "tracking/track_eval.h"

namespace hmc {

HMC_COMMAND(EvalTracks, "", "eval-tracks",
            "Score tracks_2d.csv against a synthetic shot's dots_2d.csv") {
  auto tracks = std::make_shared<std::string>();
  auto truth = std::make_shared<std::string>();
  auto json = std::make_shared<std::string>();
  app->add_option("--tracks", *tracks, "tracks_2d.csv (from hmc track)")->required();
  app->add_option("--truth", *truth, "dots_2d.csv of the shot (from hmc synth shot)")->required();
  app->add_option("--json", *json, "Write the figures to this JSON file");
  return [=] {
    PrepareOutputPaths({{*json, "--json"}}, {{*tracks, "--tracks"}, {*truth, "--truth"}});
    const TrackScore s = ScoreTracks(ReadTracks2dCsv(*tracks), ReadDots2dCsv(*truth));
    spdlog::info("eval-tracks: {}", s.BriefReport());
    if (s.has_whole) spdlog::info("eval-tracks: {}", s.WholeReport());
    if (!json->empty()) {
      nlohmann::json j = {
          {"rows", s.rows},           {"full", s.full},
          {"full_named", s.full_named}, {"partial", s.partial},
          {"partial_named", s.partial_named}, {"hidden", s.hidden},
          {"hidden_rows", s.hidden_rows}, {"wrong", s.wrong},
          {"wrong_other", s.wrong_other}, {"wrong_off", s.wrong_off},
          {"partial_half", s.partial_half}, {"partial_half_named", s.partial_half_named},
          {"median_px", s.median_px}, {"p95_px", s.p95_px},
          {"max_px", s.max_px}};
      if (s.has_whole) {
        auto bin = [](const WholeDotBin& b) {
          return nlohmann::json{{"views", b.views}, {"named", b.named},
                                {"median_px", b.median_px}, {"p95_px", b.p95_px}};
        };
        nlohmann::json bins = nlohmann::json::object();
        for (int i = 0; i < kNumCosBins; ++i) bins[CosBinName(i)] = bin(s.whole_bins[i]);
        j["whole_by_cos"] = bins;
        j["whole_from_cos_0.15"] = bin(s.whole_from_015);
      }
      WriteFileAtomic(*json, j.dump(1));
    }
    return 0;
  };
}

}  // namespace hmc
