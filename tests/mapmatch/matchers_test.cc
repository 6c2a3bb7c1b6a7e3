// The matchers on synthetic maps with known answers: ICP recovers a rigid
// motion exactly, ICCP closely, MMA an affine one exactly, correlation a
// whole-cell shift exactly, fast MSD a smooth offset; bad measurements and
// off-map points are counted and never poison the fit; options are checked.
#include <array>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "geometry.h"
#include "magnav/core/error.h"
#include "magnav/mapmatch/match.h"

namespace magnav::mapmatch {
namespace {

// Crustal-like synthetic anomaly (nT) on (lat, lon) degrees: a few bumps of
// width ~0.01°, gradients ~1e4 nT/deg.
double Bumps(double lat, double lon) {
  const double c[6][3] = {{0.02, 0.03, 80}, {0.05, 0.01, -60}, {0.035, 0.055, 70},
                          {0.07, 0.06, -50}, {0.01, 0.07, 40}, {0.06, 0.035, 55}};
  double v = 0.0;
  for (const auto& b : c) {
    const double d2 = (lat - b[0]) * (lat - b[0]) + (lon - b[1]) * (lon - b[1]);
    v += b[2] * std::exp(-d2 / (2 * 0.012 * 0.012));
  }
  return v + 30.0 * std::sin(90.0 * lat) * std::cos(70.0 * lon);
}

// A smooth "main field" with curved, distinct iso-lines (nT).
double Quadratic(double lat, double lon) { return 40000 + 300 * lat + 170 * lon + 25 * lat * lat - 11 * lat * lon + 7 * lon * lon; }

struct Truth {
  MatchPath path;  // INS + measurement
  std::vector<double> lat, lon;
};

// A curved path; measurement = the grid's own bilinear value at the truth
// (so a method that is exact in theory can be exact here).
Truth CurvedPath(const GeoGrid& g, double lat0, double lon0, double step, int n, double dlat, double dlon) {
  Truth t;
  double h = 0.3;
  double lat = lat0, lon = lon0;
  for (int k = 0; k < n; ++k) {
    t.lat.push_back(lat);
    t.lon.push_back(lon);
    t.path.k.push_back(k);
    t.path.lat_deg.push_back(lat + dlat);
    t.path.lon_deg.push_back(lon + dlon);
    t.path.measured_nT.push_back(g.Sample(0, lat, lon)->value_nT);
    h += 0.04 * std::sin(0.2 * k);
    lat += step * std::cos(h);
    lon += step * std::sin(h);
  }
  return t;
}

// A path through grid nodes (i, j) of a 0.1° grid, measured Quadratic there,
// its INS positions ins(lat, lon).
Truth OnNodes(const std::vector<std::array<int, 2>>& nodes,
              const std::function<std::array<double, 2>(double, double)>& ins) {
  Truth t;
  int k = 0;
  for (const auto& n : nodes) {
    const double lat = 0.1 * n[0], lon = 0.1 * n[1];
    const std::array<double, 2> p = ins(lat, lon);
    t.lat.push_back(lat);
    t.lon.push_back(lon);
    t.path.k.push_back(k++);
    t.path.lat_deg.push_back(p[0]);
    t.path.lon_deg.push_back(p[1]);
    t.path.measured_nT.push_back(Quadratic(lat, lon));
  }
  return t;
}

// Every matched point within tol (deg, per axis) of the truth.
void ExpectOnTruth(const MatchResult& r, const Truth& t, double tol) {
  for (std::size_t p = 0; p < t.lat.size(); ++p) {
    EXPECT_NEAR(r.lat_deg[p], t.lat[p], tol) << p;
    EXPECT_NEAR(r.lon_deg[p], t.lon[p], tol) << p;
  }
}

MatchResult InsOnly(const MatchPath& p) {
  MatchResult r;
  r.lat_deg = p.lat_deg;
  r.lon_deg = p.lon_deg;
  return r;
}

double MeanError(const MatchResult& r, const Truth& t) {
  double s = 0.0;
  for (std::size_t k = 0; k < t.lat.size(); ++k) s += std::hypot(r.lat_deg[k] - t.lat[k], r.lon_deg[k] - t.lon[k]);
  return s / static_cast<double>(t.lat.size());
}

TEST(Icp, RecoversARigidMotionExactly) {
  // Path points on grid nodes; the INS path is the truth rotated by 1.5° about
  // its centre and moved by (0.3, -0.2) cells. ICP (3-D, field unchanged by
  // the motion) finds the node correspondences and undoes the motion exactly.
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.1, 41}, {0.0, 0.1, 41}, "F", Quadratic);
  const double ang = 1.5 * M_PI / 180.0, ca = std::cos(ang), sa = std::sin(ang);
  const std::vector<std::array<int, 2>> nodes = {{10, 12}, {11, 14}, {13, 15}, {15, 15}, {17, 16}, {18, 18},
                                                 {19, 21}, {21, 22}, {23, 22}, {24, 20}, {26, 19}, {28, 19}};
  double cl = 0, cn = 0;
  for (const auto& n : nodes) {
    cl += 0.1 * n[0] / 12.0;
    cn += 0.1 * n[1] / 12.0;
  }
  const Truth t = OnNodes(nodes, [&](double lat, double lon) {
    return std::array<double, 2>{cl + ca * (lat - cl) - sa * (lon - cn) + 0.03,
                                 cn + sa * (lat - cl) + ca * (lon - cn) - 0.02};
  });
  for (const bool planar : {true, false}) {  // 2-D motion (default) and the thesis' 3-D one
    IcpOptions o;
    o.field_scale_deg_per_nT = 0.01;  // field differences dominate: the right node is unambiguous
    o.planar_motion = planar;
    const MatchResult r = MatchIcp(g, 0, t.path, o);
    ASSERT_TRUE(r.converged) << r.BriefReport();
    EXPECT_LT(r.iterations, 20);
    ExpectOnTruth(r, t, 1e-9);
    EXPECT_NEAR(r.score, 0.0, 1e-9);
    EXPECT_NE(r.notes.find("(given)"), std::string::npos);
  }
}

TEST(FitRigid, CentredAndNeverAReflection) {
  // A rotation + translation is recovered exactly (the centring matters: the
  // points are far from the origin, where an uncentred W gives a wrong R).
  Eigen::Matrix<double, 3, Eigen::Dynamic> d(3, 6), c(3, 6);
  d << 15.1, 15.3, 15.2, 15.8, 16.0, 15.5, 65.0, 65.4, 65.9, 66.1, 65.7, 65.2, 80.0, 80.3, 79.6, 80.9, 81.2, 80.1;
  const Eigen::Matrix3d R_true = Eigen::AngleAxisd(0.05, Eigen::Vector3d(0.2, -0.3, 1.0).normalized()).matrix();
  const Eigen::Vector3d t_true(0.3, -0.7, 1.1);
  c = (R_true * d).colwise() + t_true;
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  internal::FitRigid<3>(d, c, &R, &t);
  EXPECT_LT((R - R_true).norm(), 1e-12);
  EXPECT_LT((t - t_true).norm(), 1e-10);
  // A mirror image: the best proper rotation, det +1 (plain U Vᵀ would reflect).
  Eigen::Matrix<double, 3, Eigen::Dynamic> mirrored = d;
  mirrored.row(2) *= -1.0;
  internal::FitRigid<3>(d, mirrored, &R, &t);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

TEST(ClosestNode, ExactAgainstAScanOnTheMapOrAFinerGrid) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.1, 21}, {0.0, 0.1, 25}, "F", Quadratic);
  const double s = 0.002;
  for (const int sub : {1, 4}) {
    for (const auto& q : {std::array<double, 3>{1.03, 1.17, 40500.0}, std::array<double, 3>{-0.3, 2.9, 41000.0},
                          std::array<double, 3>{0.51, 0.77, 40210.0}}) {
      const internal::NodeHit h = internal::ClosestNode(g, 0, q[0], q[1], s * q[2], s, sub);
      // Scan every node of the (finer) grid.
      double best = 1e300;
      for (int i = 0; i <= 20 * sub; ++i) {
        for (int j = 0; j <= 24 * sub; ++j) {
          const double lat = 0.1 * i / sub, lon = 0.1 * j / sub;
          const double f = s * (g.Sample(0, lat, lon)->value_nT - q[2]);
          best = std::min(best, (lat - q[0]) * (lat - q[0]) + (lon - q[1]) * (lon - q[1]) + f * f);
        }
      }
      EXPECT_NEAR(h.dist2, best, 1e-12) << sub;
      EXPECT_NEAR(h.value_nT, g.Sample(0, h.lat_deg, h.lon_deg)->value_nT, 1e-9);
    }
  }
}

TEST(Iccp, RecoversARigidMotionOnCurvedContours) {
  // A field whose contours turn in every direction along the path (on nearly
  // parallel contours ICCP slides along them instead; docs/ACCURACY.md).
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  Truth t = CurvedPath(g, 0.03, 0.02, 0.001, 40, 0.0, 0.0);
  // Rotate the truth by 2° about (0.045, 0.04) and shift it by (0.002, -0.0015).
  const double ang = 2.0 * M_PI / 180.0;
  for (std::size_t k = 0; k < t.lat.size(); ++k) {
    const double a = t.lat[k] - 0.045, b = t.lon[k] - 0.04;
    t.path.lat_deg[k] = 0.045 + std::cos(ang) * a - std::sin(ang) * b + 0.002;
    t.path.lon_deg[k] = 0.04 + std::sin(ang) * a + std::cos(ang) * b - 0.0015;
  }
  const double before = MeanError(InsOnly(t.path), t);
  const MatchResult r = MatchIccp(g, 0, t.path);
  ASSERT_TRUE(r.converged) << r.BriefReport() << " error " << MeanError(r, t) << " before " << before;
  // Exact up to the piecewise-linear contours of a curved field.
  EXPECT_LT(MeanError(r, t), 0.01 * before) << before;
}

TEST(Mma, RecoversAnAffineMotionExactly) {
  // The truth sits on nodes; the INS path is an affine image of it (shear and
  // shift within 0.4 cells); the closest nodes in field are the true ones, so
  // T = (C Dᵀ)(D Dᵀ)⁻¹ maps the path back exactly.
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.1, 41}, {0.0, 0.1, 41}, "F", Quadratic);
  const Truth t = OnNodes({{10, 12}, {11, 14}, {13, 15}, {15, 15}, {17, 16}, {18, 18}, {19, 21}, {21, 22}, {23, 22}},
                          [](double lat, double lon) {
                            return std::array<double, 2>{1.01 * lat + 0.005 * lon + 0.01,
                                                         -0.004 * lat + 0.99 * lon + 0.02};
                          });
  MmaOptions o;
  o.field_scale_deg_per_nT = 0.01;
  const MatchResult r = MatchMma(g, 0, t.path, o);
  ASSERT_TRUE(r.converged) << r.BriefReport();
  EXPECT_EQ(r.iterations, 1);
  ExpectOnTruth(r, t, 1e-8);
}

TEST(Correlation, EveryMetricFindsAWholeCellShift) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  const Truth t = CurvedPath(g, 0.03, 0.02, 0.001, 40, 0.004, -0.003);
  for (const CorrelationMetric m : {CorrelationMetric::kMad, CorrelationMetric::kMsd, CorrelationMetric::kNprod}) {
    CorrelationOptions o;
    o.metric = m;
    o.search_window_deg = 0.01;
    const MatchResult r = MatchCorrelation(g, 0, t.path, o);
    ASSERT_TRUE(r.converged) << r.BriefReport();
    EXPECT_EQ(r.iterations, 21 * 21);
    EXPECT_LT(MeanError(r, t), 1e-9) << CorrelationMetricName(m);
    EXPECT_EQ(r.points_off_map, 0);
  }
  // PROD is maximised (not a distance): its best shift has the largest mean product.
  CorrelationOptions o;
  o.metric = CorrelationMetric::kProd;
  o.search_window_deg = 0.01;
  const MatchResult prod = MatchCorrelation(g, 0, t.path, o);
  EXPECT_TRUE(std::isfinite(prod.score));
  // A window that cannot reach the truth: the best shift is on its edge.
  o.metric = CorrelationMetric::kMsd;
  o.search_window_deg = 0.002;
  const MatchResult edge = MatchCorrelation(g, 0, t.path, o);
  EXPECT_FALSE(edge.converged);
  EXPECT_NE(edge.reason.find("edge of the search window"), std::string::npos);
  o.search_window_deg = 0.0005;  // half a grid step: nothing searched
  const MatchResult narrow = MatchCorrelation(g, 0, t.path, o);
  EXPECT_FALSE(narrow.converged);
  EXPECT_EQ(narrow.iterations, 1);
  EXPECT_NE(narrow.reason.find("narrower than one grid step"), std::string::npos);
}

TEST(Correlation, RotationSearchRecoversATurnedPath) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  Truth t = CurvedPath(g, 0.03, 0.02, 0.001, 40, 0.0, 0.0);
  // INS = the truth turned by 2° about its centroid and shifted by (3, -2) cells.
  double cl = 0.0, cn = 0.0;
  for (std::size_t k = 0; k < t.lat.size(); ++k) {
    cl += t.lat[k] / 40.0;
    cn += t.lon[k] / 40.0;
  }
  const double th = 2.0 * M_PI / 180.0;
  for (std::size_t k = 0; k < t.lat.size(); ++k) {
    const double a = t.lat[k] - cl, b = t.lon[k] - cn;
    t.path.lat_deg[k] = cl + std::cos(th) * a - std::sin(th) * b + 0.003;
    t.path.lon_deg[k] = cn + std::sin(th) * a + std::cos(th) * b - 0.002;
  }
  CorrelationOptions o;
  o.search_window_deg = 0.01;
  const double translation_only = MeanError(MatchCorrelation(g, 0, t.path, o), t);
  o.rotation_window_deg = 4.0;
  o.rotation_step_deg = 0.5;
  const MatchResult r = MatchCorrelation(g, 0, t.path, o);
  ASSERT_TRUE(r.converged) << r.BriefReport();
  EXPECT_EQ(r.iterations, 21 * 21 * 17);
  EXPECT_LT(MeanError(r, t), 1e-9) << r.BriefReport();
  EXPECT_GT(translation_only, 1e-4);
  EXPECT_NE(r.notes.find("rotation -2 deg"), std::string::npos) << r.notes;
}

TEST(Correlation, OffMapPointsAreExcludedAndCounted) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  // Half of the INS path lies beyond the map's northern edge; the true one inside.
  Truth t = CurvedPath(g, 0.06, 0.02, 0.001, 40, 0.02, 0.0);
  CorrelationOptions o;
  o.search_window_deg = 0.025;
  o.min_on_map_fraction = 0.3;
  const MatchResult r = MatchCorrelation(g, 0, t.path, o);
  EXPECT_LT(MeanError(r, t), 1e-9) << r.BriefReport();
  // Demanding every point on the map at the INS position only: no shift qualifies.
  o.search_window_deg = 0.001;
  o.min_on_map_fraction = 1.0;
  t.path.lat_deg.assign(t.path.size(), 5.0);  // the whole path far off the map
  const MatchResult none = MatchCorrelation(g, 0, t.path, o);
  EXPECT_FALSE(none.converged);
  EXPECT_EQ(none.lat_deg, t.path.lat_deg);  // left as the INS gave it
}

TEST(FastMsd, RecoversASmoothOffsetOnASmoothMap) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  // Offset 0.003° (3 cells) plus a slow drift; measurements from the function itself.
  Truth t = CurvedPath(g, 0.03, 0.02, 0.0008, 60, 0.0, 0.0);
  for (std::size_t k = 0; k < t.lat.size(); ++k) {
    t.path.lat_deg[k] += 0.002 + 1e-5 * static_cast<double>(k);
    t.path.lon_deg[k] += -0.002;
    t.path.measured_nT[k] = Bumps(t.lat[k], t.lon[k]);
  }
  const double before = MeanError(InsOnly(t.path), t);
  const MatchResult r = MatchFastMsd(g, 0, t.path);
  ASSERT_TRUE(r.converged) << r.BriefReport();
  EXPECT_LT(MeanError(r, t), 0.05 * before) << before << " " << r.BriefReport();
  // With the coarse stage from farther away (0.02°).
  for (std::size_t k = 0; k < t.lat.size(); ++k) t.path.lat_deg[k] += 0.018;
  FastMsdOptions o;
  o.search_window_deg = 0.03;
  const MatchResult c = MatchFastMsd(g, 0, t.path, o);
  EXPECT_LT(MeanError(c, t), 0.05 * before) << c.BriefReport();
}

TEST(FastMsd, DirectSolverIsTheJacobiFixedPoint) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  Truth t = CurvedPath(g, 0.03, 0.02, 0.0008, 30, 0.002, -0.001);
  t.path.measured_nT[4] = std::nan("");  // a point without a data term
  FastMsdOptions o;
  o.rounds = 1;
  o.epsilon_deg2 = 1e-30;
  o.max_iterations_per_round = 2000000;
  const MatchResult jacobi = MatchFastMsd(g, 0, t.path, o);
  o.solver = FastMsdSolver::kDirect;
  const MatchResult direct = MatchFastMsd(g, 0, t.path, o);
  EXPECT_EQ(direct.iterations, 1);
  for (std::size_t k = 0; k < t.lat.size(); ++k) {
    EXPECT_NEAR(direct.lat_deg[k], jacobi.lat_deg[k], 1e-10) << k;
    EXPECT_NEAR(direct.lon_deg[k], jacobi.lon_deg[k], 1e-10) << k;
  }
  EXPECT_GT(std::abs(direct.lat_deg[0] - t.path.lat_deg[0]), 1e-4);  // it did move
}

TEST(Matchers, BadMeasurementsAreCountedAndDoNotPoisonTheFit) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  const Truth t = CurvedPath(g, 0.03, 0.02, 0.001, 40, 0.003, -0.002);
  MatchPath bad = t.path;
  bad.measured_nT[7] = std::nan("");
  bad.measured_nT[20] = std::numeric_limits<double>::infinity();
  MatchOptions o;
  o.correlation.search_window_deg = 0.01;
  for (const Method m : {Method::kPoint, Method::kIcp, Method::kIccp, Method::kMma, Method::kMad, Method::kMsd,
                         Method::kProd, Method::kNprod, Method::kFastMsd}) {
    const MatchResult r = Match(m, g, 0, bad, o);
    EXPECT_EQ(r.points_bad_measurement, 2) << MethodName(m);
    EXPECT_LE(r.points_used, 38) << MethodName(m);
    for (std::size_t k = 0; k < bad.size(); ++k) {
      EXPECT_TRUE(std::isfinite(r.lat_deg[k]) && std::isfinite(r.lon_deg[k])) << MethodName(m) << " k " << k;
    }
  }
  // Correlation with the two bad points equals correlation without them.
  const MatchResult with = Match(Method::kMsd, g, 0, bad, o);
  MatchPath fewer = t.path;
  for (int k : {20, 7}) {
    fewer.k.erase(fewer.k.begin() + k);
    fewer.lat_deg.erase(fewer.lat_deg.begin() + k);
    fewer.lon_deg.erase(fewer.lon_deg.begin() + k);
    fewer.measured_nT.erase(fewer.measured_nT.begin() + k);
  }
  const MatchResult without = Match(Method::kMsd, g, 0, fewer, o);
  EXPECT_EQ(with.score, without.score);
  EXPECT_EQ(with.lat_deg[0], without.lat_deg[0]);
}

TEST(FastMsd, AWholePathOffTheMapIsLeftAloneWithAReason) {
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.001, 91}, {0.0, 0.001, 91}, "a", Bumps);
  Truth t = CurvedPath(g, 0.03, 0.02, 0.001, 20, 0.0, 0.0);
  t.path.lat_deg.assign(t.path.size(), 1.0);
  const MatchResult r = MatchFastMsd(g, 0, t.path);
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.reason.find("points on the map"), std::string::npos) << r.reason;
  EXPECT_EQ(r.lat_deg, t.path.lat_deg);
  EXPECT_EQ(r.points_off_map, 20);
}

TEST(Options, DefaultsAreValidAndBadValuesAreRefused) {
  std::string why;
  EXPECT_TRUE(IcpOptions{}.IsValid(&why)) << why;
  EXPECT_TRUE(IccpOptions{}.IsValid(&why)) << why;
  EXPECT_TRUE(MmaOptions{}.IsValid(&why)) << why;
  EXPECT_TRUE(FastMsdOptions{}.IsValid(&why)) << why;
  EXPECT_TRUE(PointMatchOptions{}.IsValid(&why)) << why;
  EXPECT_FALSE(CorrelationOptions{}.IsValid(&why));  // no default window
  EXPECT_NE(why.find("search_window_deg"), std::string::npos);
  EXPECT_EQ(IcpOptions{}.convergence_tau, 1e-5);
  EXPECT_EQ(FastMsdOptions{}.lambda_nT2_per_deg2, 1e7);
  FastMsdOptions f;
  f.lambda_nT2_per_deg2 = -1.0;
  EXPECT_FALSE(f.IsValid(&why));
  FastMsdOptions basins;
  basins.basin_half_width_deg = 0.0;  // off
  EXPECT_TRUE(basins.IsValid(&why)) << why;
  basins.basin_half_width_deg = -0.01;
  EXPECT_FALSE(basins.IsValid(&why));
  EXPECT_NE(why.find("basin_half_width_deg"), std::string::npos);
  basins.basin_half_width_deg = 0.012;
  basins.basin_step_cells = 0.0;
  EXPECT_FALSE(basins.IsValid(&why));
  EXPECT_NE(why.find("basin_step_cells"), std::string::npos);
  basins.basin_step_cells = 0.25;
  basins.basin_max_half_width_deg = 0.0;  // never widen
  EXPECT_TRUE(basins.IsValid(&why)) << why;
  basins.basin_max_half_width_deg = std::nan("");
  EXPECT_FALSE(basins.IsValid(&why));
  EXPECT_NE(why.find("basin_max_half_width_deg"), std::string::npos);
  basins.basin_max_half_width_deg = 0.048;
  basins.basin_full_mean = true;  // changes basin_mean_shift's move: needs it
  EXPECT_TRUE(basins.IsValid(&why)) << why;
  basins.basin_mean_shift = false;
  EXPECT_FALSE(basins.IsValid(&why));
  EXPECT_NE(why.find("basin_full_mean"), std::string::npos);
  FastMsdOptions from_path;
  from_path.lambda_from_path_iterations = 2;
  EXPECT_TRUE(from_path.IsValid(&why)) << why;
  from_path.lambda_from_path_iterations = -1;
  EXPECT_FALSE(from_path.IsValid(&why));
  EXPECT_NE(why.find("lambda_from_path_iterations"), std::string::npos);
  from_path.lambda_from_path_iterations = 1;
  from_path.lambda_max_nT2_per_deg2 = 1e6;  // below the floor
  EXPECT_FALSE(from_path.IsValid(&why));
  EXPECT_NE(why.find("lambda_min_nT2_per_deg2"), std::string::npos);
  from_path.lambda_max_nT2_per_deg2 = std::nan("");
  EXPECT_FALSE(from_path.IsValid(&why));
  IcpOptions i;
  i.field_scale_deg_per_nT = std::nan("");
  EXPECT_FALSE(i.IsValid(&why));
  const GeoGrid g = GeoGrid::FromFunction({0.0, 0.1, 3}, {0.0, 0.1, 3}, "a", Quadratic);
  MatchPath p{{0}, {0.1}, {0.1}, {1.0}};
  EXPECT_THROW(MatchIcp(g, 0, p, i), InputError);
  EXPECT_EQ(ParseMethod("fast-msd"), Method::kFastMsd);
  EXPECT_FALSE(ParseMethod("fastmsd").has_value());
}

}  // namespace
}  // namespace magnav::mapmatch
