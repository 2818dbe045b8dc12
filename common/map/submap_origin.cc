#include "common/map/submap_origin.h"

namespace mapmesh {

std::string_view ToString(SubmapOrigin::Verdict v) {
  switch (v) {
    case SubmapOrigin::Verdict::kValid: return "valid";
    case SubmapOrigin::Verdict::kUnsigned: return "unsigned";
    case SubmapOrigin::Verdict::kUnknownSigner: return "unknown_signer";
    case SubmapOrigin::Verdict::kForged: return "forged_signature";
  }
  return "unknown";
}

}  // namespace mapmesh
