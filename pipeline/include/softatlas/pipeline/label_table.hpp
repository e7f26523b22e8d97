// TotalSegmentator v2 "total" label table (117 classes; ct/totalsegmentator_label_table.tsv).
#pragma once

#include <string>

namespace softatlas::pipeline {

// Label id of a TotalSegmentator name ("liver" -> 5), or 0 if the name is not in the table.
int label_id(const std::string& name);
// Name of a label id ("" if unknown).
std::string label_name(int id);
// Number of rows (117).
int label_count();
// Default face budget (Table IV of paper 000: liver 5000, lung 3000, artery 1500,
// heart/stomach/spleen/diaphragm 1000, pancreas/kidneys 800, gallbladder 500; vessels as arteries).
int default_face_budget(const std::string& name);
// Soft organs built when --organs is not given (bones, muscles and the like are left out).
bool is_default_soft_organ(const std::string& name);
// FMA ontology id of a few organs ("FMA7197" for liver), "" if unknown.
std::string fma_id(const std::string& name);
// TotalSegmentator name for a BodyParts3D FMA id ("FMA7197" -> "liver"), "" if unknown.
std::string name_for_fma(const std::string& fma);

}  // namespace softatlas::pipeline
