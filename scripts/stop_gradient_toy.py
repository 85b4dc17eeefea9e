#!/usr/bin/env python3
# Issue 11, round 18 (docs/TRAINING.md): the paper's stop-gradient descent is unstable for soft
# modes driven above their natural frequency once frames share parameters (one candidate
# cause of the missing swing; the network experiments show it is not the whole story). Needs numpy; not part of the tests. Run: python3 scripts/stop_gradient_toy.py
#
# Toy: 1-D mass on a spring (stiffness k) driven by a moving anchor a(t): each frame's
# incremental potential f_t(x) = m/2 (x - 2x_{t-1} + x_{t-2})^2/dt^2 + k/2 (x - a_t)^2.
# The simulator: x_t = argmin f_t. The "network": x = Phi theta, a smooth basis in time
# (parameters shared across frames). Gradient descent with (a) the paper's stop-gradient
# gradient, (b) the least-squares (adjoint) gradient r_t = grad f_t, pushed into x_{t-1},
# x_{t-2} with -2 D W r_t, D W r_t (W = 1/(D+k)).
import warnings
import numpy as np
warnings.filterwarnings('ignore')
T, dt, m = 120, 1/30, 1.0
D = m/dt**2
t = np.arange(T)*dt
def run(k, freq, method, iters=40000):
    a = 0.05*np.sin(2*np.pi*freq*t)
    # simulator from rest at the anchor
    x = np.zeros(T); x[0]=x[1]=a[0]
    for i in range(2,T):
        x[i] = (D*(2*x[i-1]-x[i-2]) + k*a[i])/(D+k)
    # smooth basis in time: a constant and 15 cosines
    nb = 16
    Phi = np.stack([np.ones(T)] + [np.cos(np.pi*j*t/t[-1]) for j in range(1,nb)], 1)
    theta = np.linalg.lstsq(Phi, a, rcond=None)[0]  # start at the anchor (quasi-static)
    lr = 1.0/(D+k)/np.linalg.norm(Phi,2)**2 * 0.5
    for it in range(iters):
        y = Phi@theta
        r = np.zeros(T)
        r[2:] = D*(y[2:]-2*y[1:-1]+y[:-2]) + k*(y[2:]-a[2:])
        g = r.copy()
        if method=='adjoint':
            w = D/(D+k)
            g[1:-1] += -2*w*r[2:]
            g[:-2] += w*r[2:]
        # initial frames pinned as in the simulator: residual for frames 0,1 = stay at a[0]
        g[0] += (D+k)*(y[0]-a[0]); g[1] += (D+k)*(y[1]-a[0])
        theta -= lr*(Phi.T@g)
        if not np.all(np.isfinite(theta)): break
    y = Phi@theta
    best = Phi@np.linalg.lstsq(Phi, x, rcond=None)[0]
    if not np.all(np.isfinite(y)): return float('inf'), np.abs(best-x).mean()*1000
    return np.abs(y-x).mean()*1000, np.abs(best-x).mean()*1000
for k_over_D, freq in [(1.0,1.0),(0.05,1.0),(0.01,2.0),(0.001,2.0)]:
    k = k_over_D*D
    wn = np.sqrt(k/m)/(2*np.pi)
    for method in ['paper','adjoint']:
        d, best = run(k, freq, method)
        shown = f"{d:8.3f} mm" if d < 1e6 else "diverged"
        print(f"natural {wn:5.2f} Hz, drive {freq} Hz, {method:8s}: mean distance to simulator {shown} (best the basis can do {best:.3f} mm)")
