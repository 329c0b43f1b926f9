// The impedance control law of velma/control/impedance.py, compiled (setup.py builds it).
//
// One call computes what VelmaController.update computes in Python, with the same
// operations in the same order where the result depends on it: Pinocchio's crba (WORLD
// convention) and nonLinearEffects, both arms' Cartesian or joint impedance with the double
// diagonalisation of K and Λ (resp. M), the joint-limit and singularity bands, the velocity
// braking, the torque rate and magnitude limits, and the torso's joint impedance. The module
// docstring of velma/control/impedance.py states the laws and their sources; the Python class
// stays the reference (tests/velma/test_compiled_law.py compares the two).
//
// Pinocchio is used header-only: the model is rebuilt here, joint by joint, from the numbers
// of the Python pin.Model (velma/control/compiled.py), so no object crosses a library
// boundary. Units: SI (m, rad, N, N·m, s).
//
// With MuJoCo's headers (setup.py), the module also has ``Plant``: the cycle's MuJoCo side
// (_plant.hpp).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <pinocchio/multibody.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/spatial.hpp>

namespace py = pybind11;
using pinocchio::SE3;

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Vec7 = Eigen::Matrix<double, 7, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat7 = Eigen::Matrix<double, 7, 7>;
using Mat67 = Eigen::Matrix<double, 6, 7>;
using RowMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
using Array = py::array_t<double, py::array::c_style>;

// Layout of one arm's command row (velma/control/compiled.py writes it).
constexpr int kMode = 0, kRot = 1, kPos = 10, kTwist = 13, kStiff = 19, kPosture = 25, kQ = 32, kQd = 39,
              kJointStiff = 46, kLoadMass = 53, kLoadCom = 54, kCmdWidth = 57;
// Layout of one arm's output row.
constexpr int oTau = 0, oPrev = 7, oGrip = 14, oErr = 26, oWidth = 32;
// Modes: their index in impedance.py MODES (compiled.py _MODE).
constexpr int kCart = 0, kJoint = 1, kSafe = 2;

// Constants of the law, passed once from Python (each is stated once, in impedance.py and
// limits.py).
struct Constants {
  double dt, damping_ratio, safe_stiffness, safe_damping_ratio, torso_stiffness, nullspace_stiffness,
      nullspace_damping, lambda_regularisation, torque_rate_limit, torso_torque_limit;
  Vec7 arm_torque_limit, in_full, singular;
};

// Safety limits (velma.control.impedance.SafetyLimits), passed every call.
struct Limits {
  double limit_band, limit_band_torque, singularity_half_width, singularity_band, singularity_band_torque,
      band_damping_ratio, null_space_band_scale, arm_velocity, torso_velocity, velocity_time_constant;
};

double clamp(double x, double lo, double hi) { return std::min(std::max(x, lo), hi); }

const double* data_of(const Array& a, py::ssize_t size, const char* name) {
  if (a.size() != size) throw std::invalid_argument(std::string(name) + " has the wrong size");
  return a.data();
}

// D = Q (2ξ√S) Qᵀ with Λ = L Lᵀ, L⁻¹ K L⁻ᵀ = U S Uᵀ, Q = L U (impedance.py
// double_diagonalisation_damping).
template <int N>
Eigen::Matrix<double, N, N> double_diagonalisation_damping(const Eigen::Matrix<double, N, N>& stiffness,
                                                           const Eigen::Matrix<double, N, N>& inertia,
                                                           double xi) {
  Eigen::LLT<Eigen::Matrix<double, N, N>> llt(inertia);
  if (llt.info() != Eigen::Success) throw std::domain_error("inertia is not positive definite");
  Eigen::Matrix<double, N, N> chol = llt.matrixL();
  Eigen::Matrix<double, N, N> linv_k = chol.template triangularView<Eigen::Lower>().solve(stiffness);
  Eigen::Matrix<double, N, N> ktilde =
      chol.template triangularView<Eigen::Lower>().solve(Eigen::Matrix<double, N, N>(linv_k.transpose()));
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(ktilde);
  Eigen::Matrix<double, N, N> q = chol * eig.eigenvectors();
  Eigen::Matrix<double, N, 1> g = (2.0 * xi) * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return q * g.asDiagonal() * q.transpose();
}

class Law {
 public:
  Law() = default;

  // One revolute joint: kind 0/1/2 = about x/y/z, 3 = about ``axis``; the placement in the
  // parent joint's frame (R row-major, p); the body's inertia (mass, centre of mass, rotational
  // inertia about it: xx, xy, yy, xz, yz, zz), the joint's armature (kg·m², MJCF) and limits.
  void add_joint(int parent, int kind, const std::vector<double>& axis, const std::vector<double>& rot,
                 const std::vector<double>& pos, double mass, const std::vector<double>& com,
                 const std::vector<double>& inertia, double armature, double lower, double upper,
                 const std::string& name) {
    SE3 placement(Eigen::Map<const RowMat3>(rot.data()), Eigen::Vector3d(pos[0], pos[1], pos[2]));
    Eigen::VectorXd lo = Eigen::VectorXd::Constant(1, lower), hi = Eigen::VectorXd::Constant(1, upper);
    Eigen::VectorXd big = Eigen::VectorXd::Constant(1, std::numeric_limits<double>::max());
    pinocchio::JointIndex j;
    switch (kind) {
      case 0:
        j = model_.addJoint(parent, pinocchio::JointModelRX(), placement, name, big, big, lo, hi);
        break;
      case 1:
        j = model_.addJoint(parent, pinocchio::JointModelRY(), placement, name, big, big, lo, hi);
        break;
      case 2:
        j = model_.addJoint(parent, pinocchio::JointModelRZ(), placement, name, big, big, lo, hi);
        break;
      default:
        j = model_.addJoint(parent, pinocchio::JointModelRevoluteUnaligned(axis[0], axis[1], axis[2]),
                            placement, name, big, big, lo, hi);
    }
    Eigen::Matrix3d rotational;
    rotational << inertia[0], inertia[1], inertia[3], inertia[1], inertia[2], inertia[4], inertia[3], inertia[4],
        inertia[5];
    model_.appendBodyToJoint(j, pinocchio::Inertia(mass, Eigen::Vector3d(com[0], com[1], com[2]), rotational),
                             SE3::Identity());
    model_.armature[model_.joints[j].idx_v()] = armature;  // crba adds it to M's diagonal
  }

  // The two grip frames (right, left): parent joint and placement.
  void add_grip(int joint, const std::vector<double>& rot, const std::vector<double>& pos, const std::string& name) {
    SE3 placement(Eigen::Map<const RowMat3>(rot.data()), Eigen::Vector3d(pos[0], pos[1], pos[2]));
    grip_.push_back(static_cast<int>(
        model_.addFrame(pinocchio::Frame(name, joint, 0, placement, pinocchio::OP_FRAME))));
  }

  // arm_v0: the first v index of each arm (right, left); torso: its v index; constants: see
  // Constants (10 scalars, then the arm torque limits (7), the joints whose bands act in full
  // (7, 0/1) and the singular joints (7, 0/1)).
  void finish(const std::vector<int>& arm_v0, int torso, const std::vector<double>& constants) {
    if (arm_v0.size() != 2 || grip_.size() != 2 || constants.size() != 31)
      throw std::invalid_argument("finish: two arms, two grip frames and 31 constants");
    data_ = pinocchio::Data(model_);
    ik_data_ = pinocchio::Data(model_);
    v0_[0] = arm_v0[0];
    v0_[1] = arm_v0[1];
    torso_ = torso;
    const double* c = constants.data();
    k_ = Constants{c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], Vec7(c + 10), Vec7(c + 17), Vec7(c + 24)};
    for (int k = 0; k < 2; ++k) {
      lower_[k] = model_.lowerPositionLimit.segment<7>(v0_[k]);
      upper_[k] = model_.upperPositionLimit.segment<7>(v0_[k]);
      abs_limit_[k] = upper_[k].cwiseMin(-lower_[k]);
    }
    jac_.setZero(6, model_.nv);
    ready_ = true;
  }

  // The wrist band (velma/control/self_collision.py): the hand-to-forearm distance table
  // (2 sides × n5 × n6, m) over joints 5 and 6 from (lower5, lower6) in steps of ``step`` rad,
  // the band (m), the peak torque (N·m) and the damping (N·m·s/rad).
  void set_wrist(double lower5, double lower6, double step, int n5, int n6, const std::vector<double>& table,
                 double band, double torque, double damping) {
    if (static_cast<int>(table.size()) != 2 * n5 * n6 || n5 < 2 || n6 < 2 || step <= 0.0)
      throw std::invalid_argument("set_wrist: a 2 × n5 × n6 table, n5, n6 ≥ 2, step > 0");
    wrist_ = table;
    wrist_lower_[0] = lower5;
    wrist_lower_[1] = lower6;
    wrist_step_ = step;
    wrist_n_[0] = n5;
    wrist_n_[1] = n6;
    wrist_band_ = band;
    wrist_torque_ = torque;
    wrist_damping_ = damping;
  }

  // One cycle. q, v: (nv,). cmd: (2, 57) per arm (layout above). torso: (3,) setpoint
  // q, q̇ and the previous torso torque (NaN: none). prev: (2, 7) previous arm torques (NaN:
  // none). limits: (10,) SafetyLimits. out: (2, 32) per arm: torque (7), torque before the
  // velocity braking (7, the next cycle's ``prev``), grip pose (R row-major 9, p 3), Cartesian
  // error (6; untouched outside Cartesian mode). out_torso: (2,) torque and its value before
  // braking. Raises std::domain_error if a mass matrix is not positive definite.
  void update(const Array& q_in, const Array& v_in, const Array& cmd_in, const Array& torso_in, const Array& prev_in,
              const Array& limits_in, Array& out_in, Array& out_torso_in) {
    const int nv = model_.nv;
    if (out_in.size() != 2 * oWidth || out_torso_in.size() != 2) throw std::invalid_argument("out has the wrong size");
    compute(data_of(q_in, nv, "q"), data_of(v_in, nv, "v"), data_of(cmd_in, 2 * kCmdWidth, "cmd"),
            data_of(torso_in, 3, "torso"), data_of(prev_in, 14, "prev"), data_of(limits_in, 10, "limits"),
            out_in.mutable_data(), out_torso_in.mutable_data());
  }

  int nv() const { return model_.nv; }

  // One damped-least-squares iteration of the IK (velma/control/ik.py ``_dls``, its reference)
  // for arm ``k`` (0 right, 1 left) on the IK's own data: q (nq,) rad; target (12,): the grip
  // frame's rotation (row-major 9) and position (3, m); posture (nq,) or empty: the null-space
  // pull toward it; lo, hi (7,): the arm's bounds. Returns (position error m, rotation error
  // rad, converged); unless converged, q's arm block is moved in place by one step.
  py::tuple dls_step(int k, Array q_in, const Array& target_in, const Array& posture_in, const Array& lo_in,
                     const Array& hi_in, double damping, double pos_tol, double rot_tol) {
    if (!ready_) throw std::logic_error("Law.finish was not called");
    if (k != 0 && k != 1) throw std::invalid_argument("dls_step: k is 0 or 1");
    const int nv = model_.nv;
    double* q_ptr = q_in.mutable_data();
    if (q_in.size() != nv) throw std::invalid_argument("q has the wrong size");
    const double* t = data_of(target_in, 12, "target");
    const double* lo = data_of(lo_in, 7, "lo");
    const double* hi = data_of(hi_in, 7, "hi");
    const bool has_posture = posture_in.size() != 0;
    const double* posture = has_posture ? data_of(posture_in, nv, "posture") : nullptr;
    Eigen::Map<Eigen::VectorXd> q(q_ptr, nv);
    const SE3 target(Eigen::Map<const RowMat3>(t), Eigen::Vector3d(t[9], t[10], t[11]));

    pinocchio::forwardKinematics(model_, ik_data_, q);
    const SE3 cur = pinocchio::updateFramePlacement(model_, ik_data_, grip_[k]);
    const Vec6 err = pinocchio::log6(cur.actInv(target)).toVector();  // in the current grip frame
    const double perr = (target.translation() - cur.translation()).norm();
    const double rerr = err.tail<3>().norm();
    if (perr < pos_tol && rerr < rot_tol) return py::make_tuple(perr, rerr, true);

    ik_jac_.setZero(6, nv);
    pinocchio::computeFrameJacobian(model_, ik_data_, q, grip_[k], pinocchio::LOCAL, ik_jac_);
    const Mat67 jac = ik_jac_.middleCols<7>(v0_[k]);
    const Mat6 jjt = jac * jac.transpose() + damping * Mat6::Identity();
    const Eigen::PartialPivLU<Mat6> lu(jjt);
    Vec7 dq = jac.transpose() * lu.solve(err);
    if (has_posture) {  // (I − Jᵀ(JJᵀ + λI)⁻¹J) times the pull toward the posture
      const Vec7 pull = 0.1 * (Eigen::Map<const Vec7>(posture + v0_[k]) - q.segment<7>(v0_[k]));
      dq += pull - jac.transpose() * (lu.solve(jac) * pull);
    }
    const double step = dq.cwiseAbs().maxCoeff();
    if (step > 0.3) dq *= 0.3 / step;
    for (int i = 0; i < 7; ++i) q[v0_[k] + i] = std::clamp(q[v0_[k] + i] + dq[i], lo[i], hi[i]);
    return py::make_tuple(perr, rerr, false);
  }

  // ``update`` on raw buffers of the sizes it checks (the MuJoCo cycle calls it, mjcycle.hpp).
  void compute(const double* q_ptr, const double* v_ptr, const double* cmd, const double* torso, const double* prev,
               const double* l, double* out, double* out_torso) {
    if (!ready_) throw std::logic_error("Law.finish was not called");
    const int nv = model_.nv;
    Eigen::Map<const Eigen::VectorXd> q(q_ptr, nv), v(v_ptr, nv);
    const Limits lim{l[0], l[1], l[2], l[3], l[4], l[5], l[6], l[7], l[8], l[9]};

    pinocchio::crba(model_, data_, q, pinocchio::Convention::WORLD);
    pinocchio::nonLinearEffects(model_, data_, q, v);

    Mat7 mb[2];
    Vec7 qa[2], va[2];
    SE3 grip[2];
    bool cart[2];
    for (int k = 0; k < 2; ++k) {
      mb[k] = data_.M.block<7, 7>(v0_[k], v0_[k]).selfadjointView<Eigen::Upper>();
      qa[k] = q.segment<7>(v0_[k]);
      va[k] = v.segment<7>(v0_[k]);
      grip[k] = pinocchio::updateFramePlacement(model_, data_, grip_[k]);
      const int mode = static_cast<int>(cmd[k * kCmdWidth + kMode]);
      if (mode != kCart && mode != kJoint && mode != kSafe) throw std::invalid_argument("unknown mode");
      cart[k] = mode == kCart;
      double* g = out + k * oWidth + oGrip;
      Eigen::Map<RowMat3> grip_rotation(g);
      grip_rotation = grip[k].rotation();
      Eigen::Map<Eigen::Vector3d>(g + 9) = grip[k].translation();
    }

    // safety terms (impedance.py _safety)
    bool any_bands = false, any_braking = false;
    Vec7 bands[2], braking[2];
    bool near_limit = false, near_singular = false;
    Vec7 limit_edge[2], singular_edge[2], mask[2];
    for (int k = 0; k < 2; ++k) {
      limit_edge[k] = abs_limit_[k].array() - lim.limit_band;
      mask[k] = cart[k] ? k_.singular : Vec7::Zero();
      for (int i = 0; i < 7; ++i) {
        singular_edge[k][i] = mask[k][i] > 0.0 ? lim.singularity_half_width + lim.singularity_band : -1.0;
        const double aq = std::abs(qa[k][i]);
        const double centre = 0.5 * (limit_edge[k][i] + singular_edge[k][i]);
        const double half = 0.5 * (limit_edge[k][i] - singular_edge[k][i]);
        if (std::abs(aq - centre) > half) {
          if (aq > limit_edge[k][i]) near_limit = true;
          if (aq < singular_edge[k][i]) near_singular = true;
        }
      }
    }
    if (near_limit || near_singular) {
      any_bands = true;
      const double xi = lim.band_damping_ratio;
      for (int k = 0; k < 2; ++k) {
        bands[k].setZero();
        Vec7 m_diag = mb[k].diagonal();
        if (near_limit) {
          const double scale = lim.limit_band_torque / (lim.limit_band * lim.limit_band);
          const double stiff = lim.limit_band_torque / lim.limit_band;
          for (int i = 0; i < 7; ++i) {
            const double below = std::max(lower_[k][i] + lim.limit_band - qa[k][i], 0.0);
            const double above = std::max(qa[k][i] - upper_[k][i] + lim.limit_band, 0.0);
            double tau = scale * (below * below - above * above);
            const bool active = (below + above) > 0.0;
            tau += (-2.0 * xi) * std::sqrt(stiff * m_diag[i]) * va[k][i] * (active ? 1.0 : 0.0);
            bands[k][i] = tau;
          }
        }
        if (near_singular) {
          const double scale = lim.singularity_band_torque / (lim.singularity_band * lim.singularity_band);
          const double stiff = lim.singularity_band_torque / lim.singularity_band;
          Vec7 tau_s;
          for (int i = 0; i < 7; ++i) {
            const double depth =
                std::max(lim.singularity_half_width + lim.singularity_band - std::abs(qa[k][i]), 0.0) * mask[k][i];
            double tau = std::copysign(scale * depth * depth, qa[k][i]);
            const bool active = depth > 0.0;
            tau += (-2.0 * xi) * std::sqrt(stiff * m_diag[i]) * va[k][i] * (active ? 1.0 : 0.0);
            tau_s[i] = tau;
          }
          bands[k] = near_limit ? Vec7(bands[k] + tau_s) : tau_s;
        }
      }
    }
    double vmax = 0.0;
    for (int k = 0; k < 2; ++k) vmax = std::max(vmax, va[k].cwiseAbs().maxCoeff());
    if (vmax > lim.arm_velocity) {
      any_braking = true;
      for (int k = 0; k < 2; ++k) {
        Vec7 excess = va[k] - va[k].cwiseMax(-lim.arm_velocity).cwiseMin(lim.arm_velocity);
        braking[k] = (mb[k] * excess) * (-1.0 / lim.velocity_time_constant);
      }
    }

    // the laws
    Vec7 tau[2];
    if (cart[0] && cart[1]) {
      cartesian(0, 2, cmd, grip, qa, va, mb, any_bands ? bands : nullptr, lim, tau, out);
    } else if (cart[0] || cart[1]) {
      const int c = cart[0] ? 0 : 1;
      cartesian(c, c + 1, cmd, grip, qa, va, mb, any_bands ? bands : nullptr, lim, tau, out);
      joint(1 - c, 2 - c, cmd, qa, va, mb, tau);
      if (any_bands) tau[1 - c] += bands[1 - c];
    } else {
      joint(0, 2, cmd, qa, va, mb, tau);
      if (any_bands) {
        tau[0] += bands[0];
        tau[1] += bands[1];
      }
    }
    if (!wrist_.empty()) {
      for (int k = 0; k < 2; ++k) wrist_band(k, qa[k], va[k], tau[k]);
    }
    const double rate = k_.torque_rate_limit * k_.dt;
    const bool first = std::isnan(prev[0]);
    for (int k = 0; k < 2; ++k) {
      tau[k] += data_.nle.segment<7>(v0_[k]);
      const double* c = cmd + k * kCmdWidth;
      if (c[kLoadMass] != 0.0) {  // what the hand holds (payload.py payload_torque)
        jac_.setZero();
        pinocchio::getFrameJacobian(model_, data_, grip_[k], pinocchio::LOCAL, jac_);
        const Eigen::Vector3d f = c[kLoadMass] * (grip[k].rotation().transpose() * model_.gravity.linear());
        Vec6 wrench;
        wrench.head<3>() = -f;
        wrench.tail<3>() = -Eigen::Vector3d(c[kLoadCom], c[kLoadCom + 1], c[kLoadCom + 2]).cross(f);
        tau[k] += jac_.middleCols<7>(v0_[k]).transpose() * wrench;
      }
      for (int i = 0; i < 7; ++i) {
        const double lim_i = k_.arm_torque_limit[i];
        double lo = -lim_i, hi = lim_i;
        if (!first) {
          lo = std::max(prev[k * 7 + i] - rate, -lim_i);
          hi = std::min(prev[k * 7 + i] + rate, lim_i);
        }
        tau[k][i] = std::min(std::max(tau[k][i], lo), hi);
      }
      double* o = out + k * oWidth;
      Eigen::Map<Vec7>(o + oPrev) = tau[k];
      if (any_braking) {
        for (int i = 0; i < 7; ++i)
          tau[k][i] = clamp(tau[k][i] + braking[k][i], -k_.arm_torque_limit[i], k_.arm_torque_limit[i]);
      }
      Eigen::Map<Vec7>(o + oTau) = tau[k];
    }

    // the torso (impedance.py _torso)
    const int t = torso_;
    const double m_tt = data_.M(t, t);
    const double qt = q[t], vt = v[t];
    const double d_t = 2.0 * k_.damping_ratio * std::sqrt(k_.torso_stiffness * m_tt);
    double tt = k_.torso_stiffness * (torso[0] - qt) + d_t * (torso[1] - vt) + data_.nle[t];
    if (!std::isnan(torso[2])) tt = std::min(std::max(tt, torso[2] - rate), torso[2] + rate);
    tt = clamp(tt, -k_.torso_torque_limit, k_.torso_torque_limit);
    out_torso[1] = tt;
    if (std::abs(vt) > lim.torso_velocity) {
      tt -= m_tt * (vt - std::copysign(lim.torso_velocity, vt)) / lim.velocity_time_constant;
      tt = clamp(tt, -k_.torso_torque_limit, k_.torso_torque_limit);
    }
    out_torso[0] = tt;
  }

 private:
  // Cartesian impedance of arms [from, to) (impedance.py _cartesian).
  void cartesian(int from, int to, const double* cmd, const SE3* grip, const Vec7* qa, const Vec7* va,
                 const Mat7* mb, const Vec7* bands, const Limits& lim, Vec7* out, double* out_rows) {
    Vec6 p_err[2], kst[2], ev[2];
    Vec7 tau_ns[2];
    Mat67 jac[2];
    double kmin = std::numeric_limits<double>::infinity();
    for (int k = from; k < to; ++k) {
      const double* c = cmd + k * kCmdWidth;
      const SE3 target(Eigen::Map<const RowMat3>(c + kRot), Eigen::Vector3d(c[kPos], c[kPos + 1], c[kPos + 2]));
      const SE3 rel = grip[k].actInv(target);
      Eigen::Quaterniond quat(rel.rotation());
      p_err[k].head<3>() = rel.translation();
      p_err[k].tail<3>() = quat.w() < 0.0 ? Eigen::Vector3d(-quat.vec()) : Eigen::Vector3d(quat.vec());
      kst[k] = Vec6(c + kStiff);
      kmin = std::min(kmin, kst[k].minCoeff());
      const Vec7 posture(c + kPosture);
      tau_ns[k] = k_.nullspace_stiffness * (posture - qa[k]) - k_.nullspace_damping * va[k];
      if (bands != nullptr)
        tau_ns[k] += bands[k].cwiseProduct(lim.null_space_band_scale * (Vec7::Ones() - k_.in_full));
      jac_.setZero();
      pinocchio::getFrameJacobian(model_, data_, grip_[k], pinocchio::LOCAL, jac_);
      jac[k] = jac_.middleCols<7>(v0_[k]);
      const Eigen::Matrix3d& r = grip[k].rotation();
      ev[k].head<3>() = r.transpose() * Eigen::Vector3d(c[kTwist], c[kTwist + 1], c[kTwist + 2]);
      ev[k].tail<3>() = r.transpose() * Eigen::Vector3d(c[kTwist + 3], c[kTwist + 4], c[kTwist + 5]);
      ev[k] -= jac[k] * va[k];
    }
    for (int k = from; k < to; ++k) {
      if (kmin > 0.0) {
        const Vec6 s = kst[k].cwiseSqrt();
        const Mat67 js = s.asDiagonal() * jac[k];
        Mat7 g;  // G = [(K^½ J)ᵀ | τ_ns]
        g.leftCols<6>() = js.transpose();
        g.col(6) = tau_ns[k];
        Eigen::LLT<Mat7> llt(mb[k]);
        if (llt.info() != Eigen::Success) throw std::domain_error("mass matrix is not positive definite");
        const Mat7 m_inv_g = llt.solve(g);
        Mat67 prod = js * m_inv_g;
        for (int i = 0; i < 6; ++i) prod(i, i) += k_.lambda_regularisation * kst[k][i];
        Eigen::SelfAdjointEigenSolver<Mat6> eig(prod.leftCols<6>());
        const Vec6 w = eig.eigenvalues();
        const Mat6& vb = eig.eigenvectors();
        Vec6 z0 = vb.transpose() * s.cwiseProduct(ev[k]);
        Vec6 z1 = vb.transpose() * prod.col(6);
        z0.array() /= w.array().sqrt();
        z1.array() /= w.array();
        const Vec6 scaled = s.cwiseProduct(p_err[k]) + (vb * z0) * (2.0 * k_.damping_ratio) - vb * z1;
        out[k] = js.transpose() * scaled + tau_ns[k];
      } else {  // a zero stiffness: the general (Cholesky) double diagonalisation
        const Mat7 m_inv = mb[k].inverse();
        Mat6 lam_inv = jac[k] * m_inv * jac[k].transpose();
        lam_inv.diagonal().array() += k_.lambda_regularisation;
        const Mat6 lam = lam_inv.inverse();
        const Mat6 dmat = double_diagonalisation_damping<6>(Mat6(kst[k].asDiagonal()), lam, k_.damping_ratio);
        const Vec6 wrench = kst[k].cwiseProduct(p_err[k]) + dmat * ev[k] - lam * (jac[k] * (m_inv * tau_ns[k]));
        out[k] = jac[k].transpose() * wrench + tau_ns[k];
      }
      if (bands != nullptr) out[k] += bands[k].cwiseProduct(k_.in_full);
      Eigen::Map<Vec6>(out_rows + k * oWidth + oErr) = p_err[k];
    }
  }

  // The wrist band of side k added to tau (self_collision.py WristField.sample and
  // wrist_band_torque: the same operations).
  void wrist_band(int k, const Vec7& q, const Vec7& v, Vec7& tau) const {
    const int n5 = wrist_n_[0], n6 = wrist_n_[1];
    const double* table = wrist_.data() + static_cast<size_t>(k) * n5 * n6;
    const double x = std::min(std::max((q[5] - wrist_lower_[0]) / wrist_step_, 0.0), n5 - 1.000001);
    const double y = std::min(std::max((q[6] - wrist_lower_[1]) / wrist_step_, 0.0), n6 - 1.000001);
    const int i = static_cast<int>(x), j = static_cast<int>(y);
    const double f = x - i, g = y - j;
    const double d00 = table[i * n6 + j], d10 = table[(i + 1) * n6 + j], d01 = table[i * n6 + j + 1],
                 d11 = table[(i + 1) * n6 + j + 1];
    const double d = (1.0 - f) * (1.0 - g) * d00 + f * (1.0 - g) * d10 + (1.0 - f) * g * d01 + f * g * d11;
    if (d >= wrist_band_) return;
    const double g5 = ((1.0 - g) * (d10 - d00) + g * (d11 - d01)) / wrist_step_;
    const double g6 = ((1.0 - f) * (d01 - d00) + f * (d11 - d10)) / wrist_step_;
    const double norm = std::hypot(g5, g6);
    if (norm < 1e-9) return;
    const double n5v = g5 / norm, n6v = g6 / norm;
    const double s = (wrist_band_ - d) / wrist_band_;
    const double rate = n5v * v[5] + n6v * v[6];
    const double magnitude = wrist_torque_ * s * s - (rate < 0.0 ? wrist_damping_ * s * rate : 0.0);
    tau[5] += magnitude * n5v;
    tau[6] += magnitude * n6v;
  }

  // Joint impedance, modes "joint" and "safe", of arms [from, to) (impedance.py _joint).
  void joint(int from, int to, const double* cmd, const Vec7* qa, const Vec7* va, const Mat7* mb, Vec7* out) {
    Vec7 kq[2];
    double xi[2];
    double kmin = std::numeric_limits<double>::infinity();
    for (int k = from; k < to; ++k) {
      const double* c = cmd + k * kCmdWidth;
      if (static_cast<int>(c[kMode]) == kJoint) {
        kq[k] = Vec7(c + kJointStiff);
        xi[k] = k_.damping_ratio;
      } else {
        kq[k] = Vec7::Constant(k_.safe_stiffness);
        xi[k] = k_.safe_damping_ratio;
      }
      kmin = std::min(kmin, kq[k].minCoeff());
    }
    for (int k = from; k < to; ++k) {
      const double* c = cmd + k * kCmdWidth;
      const Vec7 ve = Vec7(c + kQd) - va[k];
      Vec7 damp;
      if (kmin > 0.0) {
        const Vec7 s = kq[k].cwiseSqrt();
        const Mat7 cm = mb[k].cwiseQuotient(s * s.transpose());  // C = K^-½ M K^-½
        Eigen::SelfAdjointEigenSolver<Mat7> eig(cm);
        Vec7 z = eig.eigenvectors().transpose() * s.cwiseProduct(ve);
        z = z.cwiseProduct(eig.eigenvalues().cwiseSqrt());
        damp = (2.0 * xi[k]) * s.cwiseProduct(eig.eigenvectors() * z);
      } else {
        damp = double_diagonalisation_damping<7>(Mat7(kq[k].asDiagonal()), mb[k], xi[k]) * ve;
      }
      out[k] = kq[k].cwiseProduct(Vec7(c + kQ) - qa[k]) + damp;
    }
  }

  pinocchio::Model model_;
  pinocchio::Data data_;
  pinocchio::Data ik_data_;  // the IK's (dls_step), so that the law's data_ is left alone
  Eigen::Matrix<double, 6, Eigen::Dynamic> ik_jac_;
  std::vector<int> grip_;
  int v0_[2] = {0, 0};
  int torso_ = 0;
  Constants k_{};
  Vec7 lower_[2], upper_[2], abs_limit_[2];
  Eigen::Matrix<double, 6, Eigen::Dynamic> jac_;
  bool ready_ = false;
  std::vector<double> wrist_;
  double wrist_lower_[2] = {0.0, 0.0};
  double wrist_step_ = 1.0;
  int wrist_n_[2] = {0, 0};
  double wrist_band_ = 0.0, wrist_torque_ = 0.0, wrist_damping_ = 0.0;
};

}  // namespace

#ifdef ROCO_WITH_MUJOCO
#include "_plant.hpp"
#endif

PYBIND11_MODULE(_impedance, m) {
  m.doc() =
      "The impedance control law of velma/control/impedance.py, compiled (velma/control/compiled.py), and "
      "the MuJoCo side of the cycle around it when built with MuJoCo's headers (Plant, _plant.hpp).";
  py::register_exception<std::domain_error>(m, "NotPositiveDefinite", PyExc_ArithmeticError);
  py::class_<Law>(m, "Law")
      .def(py::init<>())
      .def("add_joint", &Law::add_joint)
      .def("add_grip", &Law::add_grip)
      .def("finish", &Law::finish)
      .def("set_wrist", &Law::set_wrist)
      .def("update", &Law::update)
      .def("dls_step", &Law::dls_step, py::arg("k"), py::arg("q").noconvert(), py::arg("target"), py::arg("posture"),
           py::arg("lo"), py::arg("hi"), py::arg("damping"), py::arg("pos_tol"), py::arg("rot_tol"));
#ifdef ROCO_WITH_MUJOCO
  m.attr("MUJOCO_HEADER_VERSION") = mjVERSION_HEADER;
  py::class_<Plant>(m, "Plant")
      .def(py::init<py::object, py::object, std::uintptr_t, std::vector<int>, std::vector<int>, std::vector<int>, int,
                    std::vector<int>, std::vector<int>, std::vector<int>>())
      .def("bind", &Plant::bind, py::arg("law"), py::arg("cmd").noconvert(), py::arg("torso").noconvert(),
           py::arg("prev").noconvert(), py::arg("limits").noconvert(), py::arg("out").noconvert(),
           py::arg("out_torso").noconvert(), py::arg("q").noconvert(), py::arg("v").noconvert(),
           py::arg("parts").noconvert(), py::keep_alive<1, 2>())
      .def("bind_servos", &Plant::bind_servos, py::arg("hands").noconvert(), py::arg("head").noconvert(),
           py::arg("spread_act"), py::arg("prox_act"), py::arg("dist_act"), py::arg("prox_q"), py::arg("prox_kp"),
           py::arg("head_act"), py::arg("constants"))
      .def("cycle", &Plant::cycle)
      .def("set_state_layout", &Plant::set_state_layout)
      .def("touching", &Plant::touching)
      .def("self_contacts", &Plant::self_contacts)
      .def("gather", &Plant::gather, py::arg("out").noconvert())
      .def("bind_state_block", &Plant::bind_state_block, py::arg("block").noconvert(), py::arg("header"))
      .def("release_state_block", &Plant::release_state_block)
      .def("publish_state", &Plant::publish_state, py::arg("names_version"))
      .def("bind_world", &Plant::bind_world, py::arg("measured"), py::arg("command"), py::arg("tau_act"),
           py::arg("ft_adr"), py::arg("seqs").noconvert())
      .def("measure", &Plant::measure, py::arg("out").noconvert(), py::arg("cycles"), py::arg("holding"))
      .def("apply", &Plant::apply, py::arg("command").noconvert())
      .def("step_world", &Plant::step_world);
#endif
}
