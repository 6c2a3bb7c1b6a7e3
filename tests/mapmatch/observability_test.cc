// What a map can observe of the INS error (observability.h; issue 23 item 5).
// A plane gradient is a main-field map at its extreme: it observes the error
// across its iso-lines and nothing along them. No method may then report a
// covariance along the iso-line below the prior's there, nor say "converged".
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "magnav/mapmatch/match.h"
#include "magnav/mapmatch/observability.h"

namespace magnav::mapmatch {
namespace {

// F = 50000 + 400 lat + 200 lon nT (lat, lon deg) on a 0.05° grid: the
// gradient (400, 200) nT/deg, the iso-lines along (−200, 400)/|.|.
constexpr double kGlat = 400.0, kGlon = 200.0;
const double kIsoLat = -kGlon / std::hypot(kGlat, kGlon), kIsoLon = kGlat / std::hypot(kGlat, kGlon);

GeoGrid PlaneMap() {
  return GeoGrid::FromFunction({0.0, 0.05, 81}, {0.0, 0.05, 81}, "F_nT",
                               [](double lat, double lon) { return 50000.0 + kGlat * lat + kGlon * lon; });
}

// 60 points of 0.02° heading north-east from (1.5, 1.5); the INS = truth + a
// random walk of kDrift per step and axis from 0 (the model of the prior);
// readings = the map at the truth + N(0, 0.5²) nT.
constexpr double kDrift = 0.01;
constexpr int kPoints = 60;

struct Generated {
  MatchPath path;
  std::vector<double> true_lat, true_lon;
};

Generated MakePath(const GeoGrid& g) {
  std::mt19937 rng(23005);
  std::normal_distribution<double> n01(0.0, 1.0);
  Generated r;
  double elat = 0.0, elon = 0.0;
  for (int i = 0; i < kPoints; ++i) {
    const double tl = 1.5 + 0.014 * i, tn = 1.5 + 0.014 * i;
    if (i > 0) {
      elat += kDrift * n01(rng);
      elon += kDrift * n01(rng);
    }
    r.true_lat.push_back(tl);
    r.true_lon.push_back(tn);
    r.path.k.push_back(i);
    r.path.lat_deg.push_back(tl + elat);
    r.path.lon_deg.push_back(tn + elon);
    r.path.measured_nT.push_back(g.Sample(0, tl, tn)->value_nT + 0.5 * n01(rng));
  }
  return r;
}

double AlongIso(double a, double b, double c) {
  return a * kIsoLat * kIsoLat + 2.0 * b * kIsoLat * kIsoLon + c * kIsoLon * kIsoLon;
}

MatchOptions Options() {
  MatchOptions o;
  o.observability.prior.start_sd_deg = 0.0;
  o.observability.prior.drift_sd_deg = kDrift;
  return o;
}

// The prior's variance at the path's end, per axis.
const double kPriorEnd = kDrift * kDrift * (kPoints - 1);

TEST(Observability, APlaneGradientSeesNothingAlongItsIsoLines) {
  const GeoGrid g = PlaneMap();
  const Generated p = MakePath(g);
  const PathObservability o = ObservePath(g, 0, p.path, p.true_lat, p.true_lon, {0.0, kDrift}, 0.5);
  ASSERT_TRUE(o.valid);
  EXPECT_EQ(o.points, kPoints);
  EXPECT_LT(o.ratio_weak(), 1e-6) << o.Summary();
  EXPECT_GT(o.ratio_strong(), 1e3) << o.Summary();
  EXPECT_NEAR(std::abs(o.weak_lat * kIsoLat + o.weak_lon * kIsoLon), 1.0, 1e-9) << o.Summary();
  // Along the iso-line each point knows exactly the prior's (smoothed: the random walk
  // pinned at 0 at the start, nothing else).
  const Cov2& end = o.smoothed.back();
  EXPECT_NEAR(AlongIso(end.lat_lat, end.lat_lon, end.lon_lon), kPriorEnd, 1e-9 * kPriorEnd);
}

TEST(Observability, NoCovarianceAlongTheIsoLineBelowThePriorAndNoConverged) {
  const GeoGrid g = PlaneMap();
  const Generated p = MakePath(g);
  // A result that claims to have the truth, with a tiny covariance: the review
  // must widen it along the iso-line to the prior's and refuse "converged".
  MatchResult claimed;
  claimed.converged = true;
  claimed.lat_deg = p.true_lat;
  claimed.lon_deg = p.true_lon;
  claimed.cov_lat_lat.assign(kPoints, 1e-12);
  claimed.cov_lat_lon.assign(kPoints, 0.0);
  claimed.cov_lon_lon.assign(kPoints, 1e-12);
  const MatchOptions o = Options();
  ReviewObservability(g, 0, p.path, o.observability.prior, o.observability, &claimed);
  EXPECT_FALSE(claimed.converged);
  EXPECT_NE(claimed.reason.find("partly observable: along-iso-line error unconstrained"), std::string::npos)
      << claimed.reason;
  EXPECT_LT(claimed.observability_ratio, 1e-6);
  EXPECT_GE(AlongIso(claimed.cov_lat_lat.back(), claimed.cov_lat_lon.back(), claimed.cov_lon_lon.back()),
            kPriorEnd * (1.0 - 1e-9));

  // Every method through Match: fast MSD's published covariance and the
  // particle filter's last step, along the iso-line, are at least the prior's
  // at the end; no method says converged.
  for (const Method m : {Method::kFastMsd, Method::kPf, Method::kIcp, Method::kMma}) {
    std::vector<StepDiagnostics> steps;
    MatchOptions mo = o;
    mo.particle_filter.prior_half_width_deg = 0.05;
    mo.particle_filter.drift_sigma_deg = kDrift;
    const MatchResult r = Match(m, g, 0, p.path, mo, &steps);
    EXPECT_FALSE(r.converged) << r.BriefReport();
    EXPECT_NE(r.observability.find("map information at the path's end"), std::string::npos) << r.BriefReport();
    EXPECT_LT(r.observability_ratio, 1e-6) << r.BriefReport();
    if (m == Method::kFastMsd) {
      ASSERT_EQ(r.cov_lat_lat.size(), p.path.size());
      EXPECT_GE(AlongIso(r.cov_lat_lat.back(), r.cov_lat_lon.back(), r.cov_lon_lon.back()), kPriorEnd * (1.0 - 1e-9))
          << r.BriefReport();
    }
    if (m == Method::kPf) {
      ASSERT_EQ(steps.size(), p.path.size());
      const StepDiagnostics& d = steps.back();
      EXPECT_GE(AlongIso(d.cov_lat_lat, d.cov_lat_lon, d.cov_lon_lon), kPriorEnd * (1.0 - 1e-9)) << r.BriefReport();
    }
  }
}

TEST(Observability, AMapWithFeaturesInEveryDirectionKeepsConverged) {
  // The control: the same path over bumps whose gradients point every way (a
  // crustal-like map) observes both directions; the truth stays converged and
  // its covariance is not touched.
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.005, 801}, {0.0, 0.005, 801}, "F_nT", [](double lat, double lon) {
    return 300.0 * std::sin(lat / 0.03) * std::cos(lon / 0.04) + 150.0 * std::sin((lat + lon) / 0.02);
  });
  const Generated p = MakePath(g);
  MatchResult claimed;
  claimed.converged = true;
  claimed.lat_deg = p.true_lat;
  claimed.lon_deg = p.true_lon;
  // The drift's variance per axis: about what one reading a step can pin down
  // between the walk's steps (the linear posterior is 0.07 % larger; an
  // observable map imposes no floor).
  claimed.cov_lat_lat.assign(kPoints, 1e-4);
  claimed.cov_lat_lon.assign(kPoints, 0.0);
  claimed.cov_lon_lon.assign(kPoints, 1e-4);
  const MatchOptions o = Options();
  ReviewObservability(g, 0, p.path, o.observability.prior, o.observability, &claimed);
  EXPECT_TRUE(claimed.converged) << claimed.reason << "; " << claimed.observability;
  EXPECT_GT(claimed.observability_ratio, 10.0) << claimed.observability;
  EXPECT_EQ(claimed.cov_lat_lat.back(), 1e-4);
  EXPECT_EQ(claimed.observability.find("covariance raised"), std::string::npos) << claimed.observability;
}

TEST(Observability, TheStepFilterIsObservePathsFilteredPass) {
  // One implementation: the causal filter, stepped by hand over the path,
  // gives ObservePath's filtered covariance at every point and its ratio.
  const GeoGrid g = PlaneMap();
  const Generated p = MakePath(g);
  const InsErrorPrior prior{0.02, kDrift};
  const PathObservability o = ObservePath(g, 0, p.path, p.true_lat, p.true_lon, prior, 0.5);
  ASSERT_TRUE(o.valid);
  ObservabilityFilter f(prior);
  for (int i = 0; i < kPoints; ++i) {
    if (i > 0) f.Predict();
    const auto s = g.Sample(0, p.true_lat[i], p.true_lon[i]);
    ASSERT_TRUE(s);
    f.Update(s->dvalue_dlat_nT_per_deg, s->dvalue_dlon_nT_per_deg, 0.5);
    const Cov2 c = f.covariance();
    EXPECT_EQ(c.lat_lat, o.filtered[i].lat_lat) << i;
    EXPECT_EQ(c.lat_lon, o.filtered[i].lat_lon) << i;
    EXPECT_EQ(c.lon_lon, o.filtered[i].lon_lon) << i;
  }
  EXPECT_EQ(f.updates(), kPoints);
  EXPECT_DOUBLE_EQ(f.prior_variance_deg2(), 0.02 * 0.02 + kPriorEnd);
  const MapInformation m = f.Information();
  EXPECT_EQ(m.ratio_weak(), o.ratio_weak());
  EXPECT_EQ(m.ratio_strong(), o.ratio_strong());
  EXPECT_EQ(m.weak_bearing_deg(), o.weak_bearing_deg());
}

TEST(Observability, LiveStepsOnAPlaneArePartlyObservableAndFloorAlongTheIsoLine) {
  // What magnav-matcher does at each fix: the same review, causally. On the
  // plane the ratio is 0 from the first reading; a tiny covariance is raised
  // along the iso-line to the prior's there (nothing is known along it) and
  // stays small across it.
  const GeoGrid g = PlaneMap();
  const Generated p = MakePath(g);
  const MatchOptions mo = Options();
  StepObservability live(g, 0, mo.observability.prior, mo.observability);
  EXPECT_FALSE(live.partly_observable());  // no reading yet: a start_sd of 0 has no prior variance
  for (int i = 0; i < kPoints; ++i) {
    live.Step(p.true_lat[i], p.true_lon[i], p.path.measured_nT[i]);
    if (i == 0) continue;
    ASSERT_TRUE(live.partly_observable()) << i;
    EXPECT_LT(live.Information().ratio_weak(), 1e-6) << i;
  }
  EXPECT_GE(live.noise_sd_nT(), mo.observability.min_noise_sd_nT);
  EXPECT_LT(live.noise_sd_nT(), 1.0);  // the readings' 0.5 nT noise
  Cov2 c{1e-12, 0.0, 1e-12};
  EXPECT_TRUE(live.Floor(&c));
  EXPECT_GE(AlongIso(c.lat_lat, c.lat_lon, c.lon_lon), kPriorEnd * (1.0 - 1e-9));
  const double across = c.lat_lat + c.lon_lon - AlongIso(c.lat_lat, c.lat_lon, c.lon_lon);
  EXPECT_LT(across, 1e-9);
  // The threshold 0 = never.
  ObservabilityOptions never = mo.observability;
  never.min_information_ratio = 0.0;
  StepObservability off(g, 0, never.prior, never);
  for (int i = 0; i < kPoints; ++i) off.Step(p.true_lat[i], p.true_lon[i], p.path.measured_nT[i]);
  Cov2 d{1e-12, 0.0, 1e-12};
  EXPECT_FALSE(off.partly_observable());
  EXPECT_FALSE(off.Floor(&d));
}

TEST(Observability, LiveStepsOnARoughMapAreObservable) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.005, 801}, {0.0, 0.005, 801}, "F_nT", [](double lat, double lon) {
    return 300.0 * std::sin(lat / 0.03) * std::cos(lon / 0.04) + 150.0 * std::sin((lat + lon) / 0.02);
  });
  const Generated p = MakePath(g);
  const MatchOptions mo = Options();
  StepObservability live(g, 0, mo.observability.prior, mo.observability);
  for (int i = 0; i < kPoints; ++i) live.Step(p.true_lat[i], p.true_lon[i], p.path.measured_nT[i]);
  EXPECT_FALSE(live.partly_observable());
  EXPECT_GT(live.Information().ratio_weak(), 10.0);
  Cov2 c{1e-12, 0.0, 1e-12};
  EXPECT_FALSE(live.Floor(&c));
  EXPECT_EQ(c.lat_lat, 1e-12);
}

TEST(Observability, APriorBeyondNinetyDegreesOrNotFiniteIsRefused) {
  std::string why;
  InsErrorPrior p;
  EXPECT_TRUE(p.IsValid(&why)) << why;
  p.drift_sd_deg = InsErrorPrior::kMaxSdDeg;
  EXPECT_TRUE(p.IsValid(&why)) << why;
  for (const double bad : {-1.0, 90.5, 1e308, std::nan("")}) {
    p = InsErrorPrior{};
    p.drift_sd_deg = bad;
    EXPECT_FALSE(p.IsValid(&why)) << bad;
    p = InsErrorPrior{};
    p.start_sd_deg = bad;
    EXPECT_FALSE(p.IsValid(&why)) << bad;
    EXPECT_NE(why.find("start_sd_deg"), std::string::npos);
  }
}

}  // namespace
}  // namespace magnav::mapmatch
