// TotalSegmentator v2 "total" label table, embedded from ct/totalsegmentator_label_table.tsv
// (wasserth/TotalSegmentator, Apache-2.0) so that a fresh machine can name organs.
#include "softatlas/pipeline/label_table.hpp"

#include <cstring>

namespace softatlas::pipeline {
namespace {

struct Row {
  int id;
  const char* name;
};

constexpr Row kTable[] = {
    {1, "spleen"},
    {2, "kidney_right"},
    {3, "kidney_left"},
    {4, "gallbladder"},
    {5, "liver"},
    {6, "stomach"},
    {7, "pancreas"},
    {8, "adrenal_gland_right"},
    {9, "adrenal_gland_left"},
    {10, "lung_upper_lobe_left"},
    {11, "lung_lower_lobe_left"},
    {12, "lung_upper_lobe_right"},
    {13, "lung_middle_lobe_right"},
    {14, "lung_lower_lobe_right"},
    {15, "esophagus"},
    {16, "trachea"},
    {17, "thyroid_gland"},
    {18, "small_bowel"},
    {19, "duodenum"},
    {20, "colon"},
    {21, "urinary_bladder"},
    {22, "prostate"},
    {23, "kidney_cyst_left"},
    {24, "kidney_cyst_right"},
    {25, "sacrum"},
    {26, "vertebrae_S1"},
    {27, "vertebrae_L5"},
    {28, "vertebrae_L4"},
    {29, "vertebrae_L3"},
    {30, "vertebrae_L2"},
    {31, "vertebrae_L1"},
    {32, "vertebrae_T12"},
    {33, "vertebrae_T11"},
    {34, "vertebrae_T10"},
    {35, "vertebrae_T9"},
    {36, "vertebrae_T8"},
    {37, "vertebrae_T7"},
    {38, "vertebrae_T6"},
    {39, "vertebrae_T5"},
    {40, "vertebrae_T4"},
    {41, "vertebrae_T3"},
    {42, "vertebrae_T2"},
    {43, "vertebrae_T1"},
    {44, "vertebrae_C7"},
    {45, "vertebrae_C6"},
    {46, "vertebrae_C5"},
    {47, "vertebrae_C4"},
    {48, "vertebrae_C3"},
    {49, "vertebrae_C2"},
    {50, "vertebrae_C1"},
    {51, "heart"},
    {52, "aorta"},
    {53, "pulmonary_vein"},
    {54, "brachiocephalic_trunk"},
    {55, "subclavian_artery_right"},
    {56, "subclavian_artery_left"},
    {57, "common_carotid_artery_right"},
    {58, "common_carotid_artery_left"},
    {59, "brachiocephalic_vein_left"},
    {60, "brachiocephalic_vein_right"},
    {61, "atrial_appendage_left"},
    {62, "superior_vena_cava"},
    {63, "inferior_vena_cava"},
    {64, "portal_vein_and_splenic_vein"},
    {65, "iliac_artery_left"},
    {66, "iliac_artery_right"},
    {67, "iliac_vena_left"},
    {68, "iliac_vena_right"},
    {69, "humerus_left"},
    {70, "humerus_right"},
    {71, "scapula_left"},
    {72, "scapula_right"},
    {73, "clavicula_left"},
    {74, "clavicula_right"},
    {75, "femur_left"},
    {76, "femur_right"},
    {77, "hip_left"},
    {78, "hip_right"},
    {79, "spinal_cord"},
    {80, "gluteus_maximus_left"},
    {81, "gluteus_maximus_right"},
    {82, "gluteus_medius_left"},
    {83, "gluteus_medius_right"},
    {84, "gluteus_minimus_left"},
    {85, "gluteus_minimus_right"},
    {86, "autochthon_left"},
    {87, "autochthon_right"},
    {88, "iliopsoas_left"},
    {89, "iliopsoas_right"},
    {90, "brain"},
    {91, "skull"},
    {92, "rib_left_1"},
    {93, "rib_left_2"},
    {94, "rib_left_3"},
    {95, "rib_left_4"},
    {96, "rib_left_5"},
    {97, "rib_left_6"},
    {98, "rib_left_7"},
    {99, "rib_left_8"},
    {100, "rib_left_9"},
    {101, "rib_left_10"},
    {102, "rib_left_11"},
    {103, "rib_left_12"},
    {104, "rib_right_1"},
    {105, "rib_right_2"},
    {106, "rib_right_3"},
    {107, "rib_right_4"},
    {108, "rib_right_5"},
    {109, "rib_right_6"},
    {110, "rib_right_7"},
    {111, "rib_right_8"},
    {112, "rib_right_9"},
    {113, "rib_right_10"},
    {114, "rib_right_11"},
    {115, "rib_right_12"},
    {116, "sternum"},
    {117, "costal_cartilages"},
};

bool starts_with(const std::string& s, const char* prefix) { return s.compare(0, std::strlen(prefix), prefix) == 0; }

}  // namespace

int label_id(const std::string& name) {
  for (const Row& r : kTable)
    if (name == r.name) return r.id;
  return 0;
}

std::string label_name(int id) {
  for (const Row& r : kTable)
    if (r.id == id) return r.name;
  return "";
}

int label_count() { return static_cast<int>(sizeof(kTable) / sizeof(kTable[0])); }

int default_face_budget(const std::string& name) {
  // Table IV of paper 000 (Zhang et al.): face counts used for each organ class.
  if (name == "liver") return 5000;
  if (starts_with(name, "lung")) return 3000;
  if (name == "aorta" || starts_with(name, "pulmonary") || name == "inferior_vena_cava" ||
      name == "portal_vein_and_splenic_vein" || name == "superior_vena_cava" ||
      name.find("artery") != std::string::npos || name.find("vein") != std::string::npos)
    return 1500;
  if (name == "heart" || name == "stomach" || name == "spleen" || name == "diaphragm") return 1000;
  if (name == "pancreas" || starts_with(name, "kidney")) return 800;
  if (name == "gallbladder") return 500;
  return 1000;
}

bool is_default_soft_organ(const std::string& name) {
  static const char* kSoft[] = {"spleen",
                                "kidney_right",
                                "kidney_left",
                                "gallbladder",
                                "liver",
                                "stomach",
                                "pancreas",
                                "lung_upper_lobe_left",
                                "lung_lower_lobe_left",
                                "lung_upper_lobe_right",
                                "lung_middle_lobe_right",
                                "lung_lower_lobe_right",
                                "esophagus",
                                "trachea",
                                "small_bowel",
                                "duodenum",
                                "colon",
                                "urinary_bladder",
                                "heart",
                                "aorta",
                                "pulmonary_vein",
                                "inferior_vena_cava",
                                "portal_vein_and_splenic_vein",
                                "superior_vena_cava",
                                "pulmonary_artery"};
  for (const char* s : kSoft)
    if (name == s) return true;
  return false;
}

namespace {
struct Fma {
  const char* name;
  const char* fma;
};
// FMA ids of the organs (Foundational Model of Anatomy; BodyParts3D file names use them).
constexpr Fma kFma[] = {{"liver", "FMA7197"},           {"stomach", "FMA7148"},   {"kidney_right", "FMA7204"},
                        {"kidney_left", "FMA7205"},     {"trachea", "FMA7394"},   {"spleen", "FMA7196"},
                        {"gallbladder", "FMA7202"},     {"pancreas", "FMA7198"},  {"heart", "FMA7088"},
                        {"aorta", "FMA3734"},           {"esophagus", "FMA7131"}, {"inferior_vena_cava", "FMA10951"},
                        {"urinary_bladder", "FMA15900"}};
}  // namespace

std::string fma_id(const std::string& name) {
  for (const Fma& f : kFma)
    if (name == f.name) return f.fma;
  return "";
}

std::string name_for_fma(const std::string& fma) {
  for (const Fma& f : kFma)
    if (fma == f.fma) return f.name;
  return "";
}

}  // namespace softatlas::pipeline
