#pragma once
/// \file The frame in which an ACF body's elastic displacement is measured: built from its
/// interface nodes, `clamped` (the first interface's rigid surface) or `chord` (origin at the
/// first interface, axis through the second, roll from the first), the frame FFRF's basis holds
/// (docs/theory.md sections 7.1 and 8.4); and the reverse derivative of the elastic displacement
/// through it, for the adjoint.
#include "flexopt/bodies/quaternion.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"

#include <string>

namespace flexopt::dynamics {

/// What the frame is built from: the first interface node (r0, p0), the second's position r1
/// (chord only), the interface centroids c0, c1 in mesh coordinates.
struct FrameNodes {
  reduce::FrameCondition condition = reduce::FrameCondition::Clamped;
  bodies::Vec3 r0{0, 0, 0}, r1{0, 0, 0}, c0{0, 0, 0}, c1{0, 0, 0};
  bodies::Vec4 p0{1, 0, 0, 0};
};

/// The frame at one state: origin r (the first interface node), rotation A (frame to world),
/// the first interface's centroid c (mesh coordinates). The elastic displacement of a mesh point
/// X at world position x is A^T (x - r) - (X - c).
struct InterfaceFrame {
  bodies::Vec3 r{0, 0, 0}, c{0, 0, 0};
  bodies::Mat3 A = bodies::Mat3::Identity();
  bodies::Vec3 elastic(const bodies::Vec3 &x, const bodies::Vec3 &X) const {
    return A.transpose() * (x - r) - (X - c);
  }
};

/// The frame of section 8.4 of body `body` at time t. Throws flexopt::Error naming them if the
/// chord has turned by 90 degrees or more from the first interface's axis, or its two interfaces
/// meet (the frame is undefined there).
InterfaceFrame interface_frame(const FrameNodes &n, const std::string &body, double t);

/// The partials of w . e, e the elastic displacement of a point at world position x in the frame
/// of `n` (section 8.4, "Adjoint"): on x (to be spread over the point's element nodes by their
/// shape functions), on r0 and p0, and on r1 (zero for the clamped frame).
struct FrameCotangent {
  bodies::Vec3 x{0, 0, 0}, r0{0, 0, 0}, r1{0, 0, 0};
  bodies::Vec4 p0{0, 0, 0, 0};
};
FrameCotangent elastic_cotangent(const FrameNodes &n, const bodies::Vec3 &x, const bodies::Vec3 &w,
                                 const std::string &body, double t);

} // namespace flexopt::dynamics
