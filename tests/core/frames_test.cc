#include "magnav/core/frames.h"

#include <cmath>

#include <gtest/gtest.h>

#include "magnav/core/error.h"
#include "magnav/core/units.h"

namespace magnav {
namespace {

TEST(LocalTangentPlane, OriginMapsToZeroAndRoundTrips) {
  const LocalTangentPlane ltp({45.0, 10.0, 0.0});
  EXPECT_LT(ltp.ToNed({45.0, 10.0, 0.0}).norm(), 1e-9);
  for (double dlat : {-0.05, 0.0, 0.02}) {
    for (double dlon : {-0.1, 0.03}) {
      const Geodetic g{45.0 + dlat, 10.0 + dlon, -30.0};
      const Geodetic back = ltp.ToGeodetic(ltp.ToNed(g));
      EXPECT_NEAR(back.lat_deg, g.lat_deg, 1e-11);
      EXPECT_NEAR(back.lon_deg, g.lon_deg, 1e-11);
      EXPECT_NEAR(back.height_m, g.height_m, 1e-6);
    }
  }
}

TEST(LocalTangentPlane, AxesAreNorthEastDown) {
  const LocalTangentPlane ltp({45.0, 10.0, 0.0});
  // The reference crustal map states k_north = π/180 · M(45°) with the WGS84
  // meridional radius M: 1 mdeg of latitude ≈ 111.132 m there.
  const Eigen::Vector3d n = ltp.ToNed({45.001, 10.0, 0.0});
  EXPECT_NEAR(n.x(), 111.132, 0.01);
  EXPECT_NEAR(n.y(), 0.0, 1e-6);
  const Eigen::Vector3d e = ltp.ToNed({45.0, 10.001, 0.0});
  EXPECT_NEAR(e.y(), 78.847, 0.01);  // π/180 · N(45°) cos 45° / 1000
  EXPECT_GT(e.x(), 0.0);  // the plane curves away: tiny positive north offset
  EXPECT_LT(e.x(), 1e-3);
  const Eigen::Vector3d d = ltp.ToNed({45.0, 10.0, -10.0});
  EXPECT_NEAR(d.z(), 10.0, 1e-9);
}

TEST(LocalTangentPlane, RejectsBadOrigin) {
  EXPECT_THROW(LocalTangentPlane({91.0, 0.0, 0.0}), InputError);
  EXPECT_THROW(LocalTangentPlane({std::nan(""), 0.0, 0.0}), InputError);
}

TEST(Units, WrapAndTime) {
  EXPECT_NEAR(WrapAngle(3 * M_PI / 2), -M_PI / 2, 1e-15);
  EXPECT_DOUBLE_EQ(WrapAngle(-M_PI), M_PI);
  EXPECT_DOUBLE_EQ(WrapAngle(M_PI), M_PI);
  EXPECT_EQ(SecondsToNanos(1.5), 1500000000ull);
  EXPECT_EQ(SecondsToNanos(-1.0), 0ull);
  EXPECT_EQ(SecondsToNanos(std::nan("")), 0ull);
  EXPECT_DOUBLE_EQ(NanosToSeconds(2500000000ull), 2.5);
  EXPECT_DOUBLE_EQ(kMu0, 1.2566370614359173e-06);
  EXPECT_EQ(FormatNanosAsSeconds(300000000ull), "0.3");
  EXPECT_EQ(FormatNanosAsSeconds(12000000001ull), "12.000000001");
  EXPECT_EQ(FormatNanosAsSeconds(5000000000ull), "5");
}

}  // namespace
}  // namespace magnav
