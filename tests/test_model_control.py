"""DriveModel.to_control(): the linear part as a python-control system, same response as the model."""
import control
import numpy as np

from test_simulate import siso_model


def test_to_control_round_trip_frequency_response():
    m = siso_model()
    sys = m.to_control()
    assert sys.dt == m.Ts
    assert sys.input_labels == [p.name for p in m.inputs]
    assert sys.output_labels == [p.name for p in m.outputs]
    w = 2 * np.pi * np.array([0.5, 5.0, 50.0, 200.0])            # rad/s, below Nyquist
    resp = control.frequency_response(sys, w).complex            # (outputs, inputs, freqs)
    z = np.exp(1j * w * m.Ts)
    for k, zk in enumerate(z):
        G = m.C @ np.linalg.solve(zk * np.eye(m.n_states) - m.A, m.B) + m.D
        assert np.allclose(resp[:, :, k], G, rtol=1e-10, atol=1e-12)
    assert np.allclose(np.sort_complex(sys.poles()), np.sort_complex(np.linalg.eigvals(m.A)))
