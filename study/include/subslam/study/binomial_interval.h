// The exact (Clopper-Pearson) confidence interval of a success probability from
// `successes` out of `trials` Bernoulli trials, as Boost.Math computes it.
#ifndef SUBSLAM_STUDY_BINOMIAL_INTERVAL_H_
#define SUBSLAM_STUDY_BINOMIAL_INTERVAL_H_

namespace subslam::study {

struct ProportionInterval {
  double low = 0.0;  // in [0, 1]
  double high = 1.0;
};

// Two-sided, coverage at least `confidence`; trials > 0, 0 <= successes <= trials.
ProportionInterval BinomialInterval(int successes, int trials, double confidence = 0.95);

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_BINOMIAL_INTERVAL_H_
