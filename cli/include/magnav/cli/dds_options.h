// Command-line options every DDS program shares (the magnav tool's replay and
// record commands, and each service): domain id, extra XML profiles,
// participant profile, ROS 2 names. Part of the command-line module that tools and
// services both sit on; the DDS adapter itself has no command line.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "magnav/dds/node.h"

namespace magnav::cli {

struct DdsArgs {
  int domain_id = -1;               // -1: $MAGNAV_DOMAIN_ID, else $ROS_DOMAIN_ID, else 0
  std::string profiles_file;        // extra Fast DDS XML profiles
  std::string participant_profile;  // "": $MAGNAV_DDS_PARTICIPANT or magnav_loopback
  bool ros2_names = false;          // ROS 2 topic/type names; false: $MAGNAV_ROS2_NAMES decides

  dds::NodeOptions ToNodeOptions(const std::string& name) const {
    dds::NodeOptions o;
    o.name = name;
    if (domain_id >= 0) o.domain_id = domain_id;
    o.profiles_file = profiles_file;
    o.participant_profile = participant_profile;
    if (ros2_names) o.ros2_names = true;
    return o;
  }
};

inline void AddDdsOptions(CLI::App& app, DdsArgs* out) {
  app.add_option("--domain", out->domain_id, "DDS domain id (default $MAGNAV_DOMAIN_ID, $ROS_DOMAIN_ID, 0)")
      ->check(CLI::Range(0, 232));
  app.add_option("--dds-profiles", out->profiles_file, "extra Fast DDS XML profiles file (e.g. config/magnav_multihost.xml)")
      ->check(CLI::ExistingFile);
  app.add_option("--dds-participant", out->participant_profile,
                 "participant profile (default magnav_loopback: 127.0.0.1 + shared memory only)");
  app.add_flag("--ros2-names", out->ros2_names,
               "ROS 2 names on the wire: topics rt/magnav/..., types magnav::msg::dds_::..._ (or $MAGNAV_ROS2_NAMES=1; "
               "docs/INTEROP.md)");
}

}  // namespace magnav::cli
