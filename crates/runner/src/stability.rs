//! Closed-loop stability of controller and plant, checked before a run from the exact linear
//! tick of the simulator (delay, hold and ADC averaging included).

use crate::controller::LinearController;
use nalgebra::DMatrix;
use plant_sim::LinearTick;

/// Spectral radius of the sampled closed loop (< 1 is stable).
///
/// Closed-loop state `[x, u[k−1], controller state, last sample (gap, accel)]`:
/// `u = C c + D y`, `x⁺ = Φx + g_prev·u[k−1] + g_now·u`, `y⁺ = Y_x x + y_prev·u[k−1] + y_now·u`,
/// `c⁺ = A c + B y`.
pub fn spectral_radius(plant: &LinearTick, ctrl: &LinearController) -> f64 {
    let (n, nc) = (plant.phi.nrows(), ctrl.a.nrows());
    let (iu, ic, iy) = (n, n + 1, n + 1 + nc);
    let size = iy + 2;
    // The command as a row over the closed-loop state.
    let mut u = DMatrix::zeros(1, size);
    u.view_mut((0, ic), (1, nc)).copy_from(&ctrl.c);
    u.view_mut((0, iy), (1, 2)).copy_from(&ctrl.d);
    let mut m = DMatrix::zeros(size, size);
    m.view_mut((0, 0), (n, n)).copy_from(&plant.phi);
    m.view_mut((0, iu), (n, 1)).copy_from(&plant.g_prev);
    m.view_mut((iu, 0), (1, size)).copy_from(&u);
    m.view_mut((ic, ic), (nc, nc)).copy_from(&ctrl.a);
    m.view_mut((ic, iy), (nc, 2)).copy_from(&ctrl.b);
    m.view_mut((iy, 0), (2, n)).copy_from(&plant.y_x);
    m.view_mut((iy, iu), (2, 1)).copy_from(&plant.y_prev);
    let gu = &plant.g_now * &u;
    let yu = &plant.y_now * &u;
    let mut top = m.view_mut((0, 0), (n, size));
    top += gu;
    let mut bottom = m.view_mut((iy, 0), (2, size));
    bottom += yu;
    m.complex_eigenvalues()
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max)
}
