// Stage 5, connect: inter-organ connection springs from proximity (k-d tree search).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "softatlas/io/organ_set.hpp"

namespace softatlas::pipeline {

struct ConnectOptions {
  double distance_mm = 4.0;  // surface points closer than this are connected
  double spacing_mm = 6.0;   // thinning: at most one spring per disc of this radius on organ A
  double stiffness = 50.0;   // N/m per spring
  // Anchors (organ sets from a CT, in RAS): the posterior surface of a supine patient's organ
  // rests on the body wall, so the `anchor_count` posterior-most vertices (RAS -y), at least
  // anchor_spacing_mm apart, are written as fixed vertices. 0 turns anchors off.
  int anchor_count = 6;
  double anchor_spacing_mm = 15.0;
  // Default anatomical pairs (always tried, and any other pair closer than distance_mm).
  std::vector<std::pair<std::string, std::string>> pairs = {
      {"liver", "gallbladder"}, {"liver", "diaphragm"},          {"stomach", "spleen"},     {"stomach", "diaphragm"},
      {"liver", "stomach"},     {"liver", "inferior_vena_cava"}, {"kidney_left", "spleen"}, {"pancreas", "stomach"},
      {"heart", "aorta"},       {"heart", "pulmonary_artery"}};
};

struct PairReport {
  std::string organ_a, organ_b;
  double closest_mm = 0.0;
  size_t springs = 0;
  bool default_pair = false;
};

std::vector<io::Connection> connect_organs(const std::vector<io::OrganEntry>& organs, const ConnectOptions& options,
                                           std::vector<PairReport>* report);

}  // namespace softatlas::pipeline
