"""The load-history-to-sensor-history map of a viscoelastic half-space (or of viscoelastic layers of one
relaxation shape) as a LinearOperator.

It is a Kronecker product: the elastic map of one time (:class:`LoadToSensor` of the glassy skin,
E(0)) on every frame, then, for strain, the creep convolution over the frames (the lower
triangular matrix of :func:`.hereditary.convolution_matrix`, times E(0)); for stress the time map
is the identity (under prescribed tractions the stress does not depend on the modulus). The adjoint
is the transpose of each factor, so the dot test holds to round-off.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse.linalg import LinearOperator

from .hereditary import check_times, convolution_matrix


class HistoryOperator(LinearOperator):
    """Traction history (Pa) to stress (Pa) or TENSOR strain history at sensors at one depth.

    Parameters
    ----------
    skin : ViscoelasticHalfSpace or ViscoelasticLayeredHalfSpace
        The layered skin needs one relaxation shape (``relaxation_shape()``); its creep is that shape's.
    shape, spacing, sensors, depth, components, loads, quantity, periodic
        As :class:`tactilab.forward.halfspace.LoadToSensor`.
    times : sequence of float
        Frame times in s, strictly increasing (zero load before the first).

    Attributes
    ----------
    spatial : LoadToSensor
        The map of one frame.
    time_matrix : ndarray, shape (n_times, n_times)
        The map over frames (identity for stress).
    """

    def __init__(self, skin, shape, spacing, times, sensors=None, depth=1e-3, components=("zz",), loads=("p",),
                 quantity="stress", periodic=False):
        self.times = check_times(times)
        self.spatial = skin.instantaneous.operator(shape, spacing, sensors=sensors, depth=depth,
                                                   components=components, loads=loads, quantity=quantity,
                                                   periodic=periodic)
        n_t = len(self.times)
        law = skin.relaxation_shape() if hasattr(skin, "relaxation_shape") else skin.prony  # refuses mixed layers
        if quantity == "strain" and law is not None:
            self.time_matrix = law.E_0 * convolution_matrix(law.kernel("creep"), self.times)
        else:
            self.time_matrix = np.eye(n_t)
        self.n_model, self.n_data = self.spatial.shape[1], self.spatial.shape[0]
        super().__init__(dtype=np.float64, shape=(n_t * self.n_data, n_t * self.n_model))

    def _matvec(self, v):
        frames = np.asarray(v, dtype=float).reshape(len(self.times), self.n_model)
        data = self.spatial.matmat(frames.T).T  # (n_t, n_data)
        return (self.time_matrix @ data).ravel()

    def _rmatvec(self, d):
        frames = self.time_matrix.T @ np.asarray(d, dtype=float).reshape(len(self.times), self.n_data)
        return self.spatial.rmatmat(frames.T).T.ravel()
