// Pinocchio's ABA in C++, timed the way benches/chain.rs times admit_rs's: the same URDF
// files, 1024 pseudo-random states (q, v, tau in [-2, 2], tau x5) cycled, the tip force
// (-10, 0.5, 1) N at the tip origin as an external wrench on the last joint. Built and run
// by benches/aba_vs_pinocchio.py --cpp (needs the `pin` wheel's headers and libraries, Eigen
// 3.4 headers and a C++17 compiler). Prints "<file> <ns per call>" per arm.
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace pin = pinocchio;

int main(int argc, char **argv) {
  for (int a = 1; a + 1 < argc; a += 2) {
    std::ifstream in(argv[a]);
    std::stringstream text;
    text << in.rdbuf();
    pin::Model model;
    pin::urdf::buildModelFromXML(text.str(), model);
    pin::Data data(model);
    const auto frame = model.getFrameId(argv[a + 1]);
    const auto last = model.frames[frame].parentJoint;
    std::mt19937_64 rng(0);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    const int n_states = 1024;
    std::vector<Eigen::VectorXd> qs, vs, taus;
    std::vector<pin::container::aligned_vector<pin::Force>> fexts;
    for (int k = 0; k < n_states; ++k) {
      Eigen::VectorXd q(model.nq), v(model.nv), tau(model.nv);
      int iq = 0;
      for (int j = 1; j < model.njoints; ++j) {
        const double angle = u(rng);
        if (model.joints[j].nq() == 2) {
          q[iq++] = std::cos(angle);
          q[iq++] = std::sin(angle);
        } else {
          q[iq++] = angle;
        }
      }
      for (int i = 0; i < model.nv; ++i) v[i] = u(rng);
      for (int i = 0; i < model.nv; ++i) tau[i] = 5.0 * u(rng);
      pin::forwardKinematics(model, data, q);
      pin::updateFramePlacements(model, data);
      const Eigen::Vector3d f(-10.0, 0.5, 1.0);
      const Eigen::Vector3d p = data.oMf[frame].translation();
      pin::Force world(f, p.cross(f));
      pin::container::aligned_vector<pin::Force> fext(model.njoints, pin::Force::Zero());
      fext[last] = data.oMi[last].actInv(world);
      qs.push_back(q);
      vs.push_back(v);
      taus.push_back(tau);
      fexts.push_back(fext);
    }
    double best = 1e300, sink = 0.0;
    for (int rep = 0; rep < 7; ++rep) {
      const int calls = 200000;
      const auto start = std::chrono::steady_clock::now();
      for (int c = 0; c < calls; ++c) {
        const int k = c & (n_states - 1);
        sink += pin::aba(model, data, qs[k], vs[k], taus[k], fexts[k])[0];
      }
      const double ns =
          std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start)
              .count() / calls;
      best = ns < best ? ns : best;
    }
    std::printf("%s %.1f %g\n", argv[a], best, sink * 0.0);
  }
  return 0;
}
