#include "subslam/study/binomial_interval.h"

#include <boost/math/distributions/binomial.hpp>

namespace subslam::study {

ProportionInterval BinomialInterval(int successes, int trials, double confidence) {
  using boost::math::binomial_distribution;
  const double tail = (1.0 - confidence) / 2.0;
  return {binomial_distribution<double>::find_lower_bound_on_p(trials, successes, tail),
          binomial_distribution<double>::find_upper_bound_on_p(trials, successes, tail)};
}

}  // namespace subslam::study
