#include "tissue/viscoelastic.hpp"

#include <cmath>

namespace stroma {

ViscoStep visco_step(const PronySeries& s, double h) {
  ViscoStep st;
  st.terms = s.terms;
  for (int i = 0; i < s.terms; ++i) {
    const double x = h / s.tau[i];
    st.decay[i] = std::exp(-x);
    const double gamma = x > 1e-8 ? -std::expm1(-x) / x : 1.0 - 0.5 * x;  // (1 − e^(−x))/x
    st.gg[i] = s.g[i] * gamma;
    st.c -= s.g[i] * (1.0 - gamma);
  }
  return st;
}

}  // namespace stroma
