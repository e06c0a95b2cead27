"""The confidence levels rattlefit reports at, and their quantiles.

Every interval is a 95 % interval and every one-sided allowance for the noise of a cost is a
95 % one; these are the only definitions of the quantiles they use.
"""

from __future__ import annotations

#: The standard normal's 97.5 % quantile: a two-sided 95 % interval is ±Z95 σ.
Z95 = 1.959963984540054
#: The standard normal's 95 % quantile as conventionally quoted: a one-sided 95 % allowance
#: for a noisy cost difference is Z95_ONE_SIDED of its standard deviations.
Z95_ONE_SIDED = 1.645
#: The 95 % quantile of χ² with one degree of freedom (Z95²): the profile-likelihood threshold.
CHI2_1_95 = Z95**2
