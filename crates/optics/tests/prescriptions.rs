//! Prescriptions against closed forms: the conic's sag and slope, Zernike terms in both
//! orders written out by hand (Noll 1976, Table 1; the Fringe table of Zemax's manual), every
//! term's slope against a central difference of its sag, the sag grid reproducing a
//! quadratic, an off-axis segment, and the nose compensation on spheres against the offset
//! sphere's exact geometry.

use optics::nose::{contact, tightness};
use optics::polynomial::XyTerm;
use optics::zernike::{fringe, noll, FRINGE_TERMS};
use optics::{Conic, Prescription, SagGrid, XyPolynomial, Zernike, ZernikeOrder};

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

#[test]
fn conic_sag_and_slope_are_the_closed_forms() {
    // A paraboloid (k = −1) is exactly z = c r²/2; a sphere R − √(R² − r²).
    let para = Conic {
        curvature_per_m: 1.0 / 0.2,
        conic: -1.0,
        even_asphere: vec![],
    };
    let s = para.sag(0.012, -0.005);
    let r2: f64 = 0.012 * 0.012 + 0.005 * 0.005;
    assert!(close(s.z_m, r2 / 0.4, 1e-12), "{}", s.z_m);
    assert!(close(s.dz_dx, 0.012 / 0.2, 1e-12) && close(s.dz_dy, -0.005 / 0.2, 1e-12));
    let rs = 0.05;
    let sphere = Conic {
        curvature_per_m: 1.0 / rs,
        conic: 0.0,
        even_asphere: vec![],
    };
    let (x, y) = (0.02, 0.015);
    let r: f64 = libm::hypot(x, y);
    let root = (rs * rs - r * r).sqrt();
    let s = sphere.sag(x, y);
    assert!(close(s.z_m, rs - root, 1e-12));
    assert!(close(s.dz_dx, x / root, 1e-12) && close(s.dz_dy, y / root, 1e-12));
    // Even asphere terms: α₁ r² + α₂ r⁴ + α₃ r⁶ on a plane.
    let asph = Conic {
        curvature_per_m: 0.0,
        conic: 0.0,
        even_asphere: vec![0.5, -30.0, 2e4],
    };
    let s = asph.sag(x, y);
    let want = 0.5 * r.powi(2) - 30.0 * r.powi(4) + 2e4 * r.powi(6);
    let slope = 1.0 - 120.0 * r.powi(2) + 1.2e5 * r.powi(4); // dz/dr / r
    assert!(close(s.z_m, want, 1e-12) && close(s.dz_dx, slope * x, 1e-12));
    // Beyond the conic's limit radius the sag is undefined.
    assert!(sphere.sag(0.06, 0.0).z_m.is_nan());
    assert!((sphere.limit_radius_m() - rs).abs() < 1e-15);
}

#[test]
fn noll_and_fringe_numbering_follow_their_tables() {
    // Noll 1976 Table 1: j → (n, m), m > 0 cos, m < 0 sin.
    let table = [
        (1, 0, 0),
        (2, 1, 1),
        (3, 1, -1),
        (4, 2, 0),
        (5, 2, -2),
        (6, 2, 2),
        (7, 3, -1),
        (8, 3, 1),
        (9, 3, -3),
        (10, 3, 3),
        (11, 4, 0),
        (12, 4, 2),
        (13, 4, -2),
        (14, 4, 4),
        (15, 4, -4),
        (16, 5, 1),
        (22, 6, 0),
        (37, 8, 0),
    ];
    for (j, n, m) in table {
        assert_eq!(noll(j), (n, m), "Noll j = {j}");
    }
    // Fringe: 4 defocus, 9 primary spherical, 16 secondary, 25 tertiary, 36, 37 (n = 12).
    let table = [
        (1, 0, 0),
        (2, 1, 1),
        (3, 1, -1),
        (4, 2, 0),
        (5, 2, 2),
        (6, 2, -2),
        (7, 3, 1),
        (8, 3, -1),
        (9, 4, 0),
        (10, 3, 3),
        (11, 3, -3),
        (12, 4, 2),
        (13, 4, -2),
        (14, 5, 1),
        (15, 5, -1),
        (16, 6, 0),
        (17, 4, 4),
        (25, 8, 0),
        (26, 5, 5),
        (36, 10, 0),
        (37, 12, 0),
    ];
    for (j, n, m) in table {
        assert_eq!(fringe(j), (n, m), "Fringe j = {j}");
    }
}

fn single(order: ZernikeOrder, j: usize, coefficient: f64, radius: f64) -> Zernike {
    let mut coefficients_m = vec![0.0; j];
    coefficients_m[j - 1] = coefficient;
    Zernike {
        order,
        norm_radius_m: radius,
        coefficients_m,
    }
}

#[test]
fn zernike_terms_are_the_written_polynomials() {
    let big_r = 0.01;
    let (x, y) = (0.0042, -0.0061);
    let (rho, th) = (libm::hypot(x, y) / big_r, libm::atan2(y, x));
    let a = 2e-6;
    let cases: [(ZernikeOrder, usize, f64); 8] = [
        (
            ZernikeOrder::Standard,
            4,
            3f64.sqrt() * (2.0 * rho.powi(2) - 1.0),
        ),
        (
            ZernikeOrder::Standard,
            6,
            6f64.sqrt() * rho.powi(2) * libm::cos(2.0 * th),
        ),
        (
            ZernikeOrder::Standard,
            7,
            8f64.sqrt() * (3.0 * rho.powi(3) - 2.0 * rho) * libm::sin(th),
        ),
        (
            ZernikeOrder::Standard,
            11,
            5f64.sqrt() * (6.0 * rho.powi(4) - 6.0 * rho.powi(2) + 1.0),
        ),
        (
            ZernikeOrder::Fringe,
            8,
            (3.0 * rho.powi(3) - 2.0 * rho) * libm::sin(th),
        ),
        (ZernikeOrder::Fringe, 10, rho.powi(3) * libm::cos(3.0 * th)),
        (
            ZernikeOrder::Fringe,
            25,
            70.0 * rho.powi(8) - 140.0 * rho.powi(6) + 90.0 * rho.powi(4) - 20.0 * rho.powi(2)
                + 1.0,
        ),
        (
            ZernikeOrder::Fringe,
            37,
            924.0 * rho.powi(12) - 2772.0 * rho.powi(10) + 3150.0 * rho.powi(8)
                - 1680.0 * rho.powi(6)
                + 420.0 * rho.powi(4)
                - 42.0 * rho.powi(2)
                + 1.0,
        ),
    ];
    for (order, j, want) in cases {
        let z = single(order, j, a, big_r).sag(x, y).z_m;
        assert!(
            close(z, a * want, 1e-12),
            "{order:?} {j}: {z} vs {}",
            a * want
        );
    }
    // Slopes written out: Noll 4 (defocus) dz/dx = a√3·4ρ·(x/r)/R = a√3·4x/R².
    let s = single(ZernikeOrder::Standard, 4, a, big_r).sag(x, y);
    assert!(close(
        s.dz_dx,
        a * 3f64.sqrt() * 4.0 * x / (big_r * big_r),
        1e-12
    ));
    // Fringe 5, ρ² cos 2θ = (x² − y²)/R²: dz/dx = 2ax/R², dz/dy = −2ay/R².
    let s = single(ZernikeOrder::Fringe, 5, a, big_r).sag(x, y);
    assert!(close(s.z_m, a * (x * x - y * y) / (big_r * big_r), 1e-12));
    assert!(close(s.dz_dx, 2.0 * a * x / (big_r * big_r), 1e-12));
    assert!(close(s.dz_dy, -2.0 * a * y / (big_r * big_r), 1e-12));
    // Fringe 11, ρ³ sin 3θ = (3x²y − y³)/R³.
    let s = single(ZernikeOrder::Fringe, 11, a, big_r).sag(x, y);
    assert!(close(s.dz_dx, a * 6.0 * x * y / big_r.powi(3), 1e-12));
    assert!(close(
        s.dz_dy,
        a * (3.0 * x * x - 3.0 * y * y) / big_r.powi(3),
        1e-12
    ));
}

#[test]
fn every_term_slope_is_the_derivative_of_its_sag_including_on_the_axis() {
    let big_r = 0.01;
    let h = 1e-7;
    for order in [ZernikeOrder::Standard, ZernikeOrder::Fringe] {
        for j in 1..=FRINGE_TERMS {
            let z = single(order, j, 1e-6, big_r);
            for (x, y) in [(0.003, 0.0071), (-0.0088, 0.0012), (0.0, 0.0), (1e-9, 0.0)] {
                let s = z.sag(x, y);
                let dx = (z.sag(x + h, y).z_m - z.sag(x - h, y).z_m) / (2.0 * h);
                let dy = (z.sag(x, y + h).z_m - z.sag(x, y - h).z_m) / (2.0 * h);
                let scale = 1e-6 / big_r * 100.0;
                assert!(
                    (s.dz_dx - dx).abs() < 1e-7 * scale,
                    "{order:?} {j} at ({x}, {y}): {} vs {dx}",
                    s.dz_dx
                );
                assert!(
                    (s.dz_dy - dy).abs() < 1e-7 * scale,
                    "{order:?} {j} at ({x}, {y}): {} vs {dy}",
                    s.dz_dy
                );
            }
        }
    }
}

#[test]
fn xy_polynomial_and_its_slopes() {
    let p = XyPolynomial {
        norm_radius_m: 0.01,
        terms: vec![
            XyTerm {
                x_power: 2,
                y_power: 0,
                coefficient_m: 1e-6,
            },
            XyTerm {
                x_power: 1,
                y_power: 3,
                coefficient_m: -2e-6,
            },
        ],
    };
    let (x, y) = (0.004, -0.007);
    let (u, v) = (x / 0.01, y / 0.01);
    let s = p.sag(x, y);
    assert!(close(s.z_m, 1e-6 * u * u - 2e-6 * u * v.powi(3), 1e-12));
    assert!(close(s.dz_dx, (2e-6 * u - 2e-6 * v.powi(3)) / 0.01, 1e-12));
    assert!(close(s.dz_dy, -6e-6 * u * v * v / 0.01, 1e-12));
}

#[test]
fn sag_grid_passes_its_nodes_and_reproduces_a_quadratic_with_its_slope() {
    // z = a x² + b xy + c y² + d x + e on a 41 × 31 grid at 0.5 mm.
    let f = |x: f64, y: f64| 3.0 * x * x - 2.0 * x * y + 5.0 * y * y + 0.01 * x + 1e-6;
    let (columns, rows, pitch) = (41usize, 31usize, 0.5e-3);
    let (hx, hy) = (20.0 * pitch, 15.0 * pitch);
    let mut sag_m = Vec::new();
    for row in 0..rows {
        for col in 0..columns {
            sag_m.push(f(-hx + col as f64 * pitch, hy - row as f64 * pitch));
        }
    }
    let g = SagGrid {
        pitch_m: [pitch, pitch],
        columns,
        rows,
        sag_m,
    };
    // A node: row 3 from the top, column 7.
    let (x, y) = (-hx + 7.0 * pitch, hy - 3.0 * pitch);
    assert!((g.sag(x, y).z_m - f(x, y)).abs() < 1e-15);
    // Between nodes, away from the edges: exact for a quadratic.
    for (x, y) in [(0.00123, -0.00217), (-0.0061, 0.0033), (0.0, 0.0)] {
        let s = g.sag(x, y);
        assert!((s.z_m - f(x, y)).abs() < 1e-15, "{} vs {}", s.z_m, f(x, y));
        assert!((s.dz_dx - (6.0 * x - 2.0 * y + 0.01)).abs() < 1e-12);
        assert!((s.dz_dy - (-2.0 * x + 10.0 * y)).abs() < 1e-12);
    }
    // The slope is continuous across a node line.
    let (xn, e) = (-hx + 12.0 * pitch, 1e-12);
    let (l, r) = (g.sag(xn - e, 0.001).dz_dx, g.sag(xn + e, 0.001).dz_dx);
    assert!((l - r).abs() < 1e-9);
}

#[test]
fn an_off_axis_segment_is_the_parent_shifted_to_zero_at_its_centre() {
    let parent = Conic {
        curvature_per_m: 1.0 / 0.3,
        conic: -1.0,
        even_asphere: vec![],
    };
    let seg = Prescription {
        base: Some(parent.clone()),
        decenter_m: [0.04, 0.0],
        aperture_radius_m: 0.01,
        ..Prescription::default()
    };
    assert!(seg.sag(0.0, 0.0).z_m.abs() < 1e-18);
    let s = seg.sag(0.005, 0.002);
    let want = (0.045f64.powi(2) + 0.002f64.powi(2) - 0.04f64.powi(2)) / 0.6;
    assert!(close(s.z_m, want, 1e-12));
    assert!(close(s.dz_dx, 0.045 / 0.3, 1e-12));
}

#[test]
fn nose_compensation_on_a_sphere_is_the_offset_sphere() {
    // A convex sphere (radius Rs, toward the tool) cut by a nose R: the nose centre runs on
    // the concentric sphere Rs + R; a concave one on Rs − R. Height toward the tool = −sag.
    let nose = 0.5e-3;
    for rs in [0.02, -0.02, 0.1] {
        let p = Prescription::of_base(Conic {
            curvature_per_m: 1.0 / rs,
            conic: 0.0,
            even_asphere: vec![],
        });
        for r_t in [0.0, 0.003, 0.0071, 0.012] {
            for theta in [0.0, 1.3, 4.0] {
                let c = contact(&p, nose, r_t, theta).expect("a sphere's contact settles");
                // Sphere centre at z = Rs (sag frame), height −Rs; nose centre on radius |Rs ± R|.
                let (centre_h, offset) = if rs > 0.0 {
                    (-rs, rs + nose)
                } else {
                    (-rs, -rs - nose)
                };
                let exact = if rs > 0.0 {
                    centre_h + (offset * offset - r_t * r_t).sqrt() - nose
                } else {
                    centre_h - (offset * offset - r_t * r_t).sqrt() - nose
                };
                assert!(
                    (c.tip_height_m - exact).abs() < 1e-12,
                    "Rs {rs} r {r_t}: {} vs {exact}",
                    c.tip_height_m
                );
                // Contact on the line from the sphere's centre through the nose centre.
                let contact_exact = r_t * rs.abs() / offset;
                assert!((c.contact_radius_m - contact_exact).abs() < 1e-12);
                // R·κ: the sphere's curvature 1/Rs (concave positive).
                assert!((tightness(&p, nose, &c, theta) - (-nose / rs)).abs() < 1e-6);
            }
        }
        // Without compensation the cut would be R(1/cos α − 1) deep at the contact.
    }
}

#[test]
fn a_concave_region_tighter_than_the_nose_is_reported() {
    // A concave sphere of radius 0.4 mm under a 0.5 mm nose: R·κ = 1.25.
    let p = Prescription::of_base(Conic {
        curvature_per_m: -1.0 / 0.4e-3,
        conic: 0.0,
        even_asphere: vec![],
    });
    let c = contact(&p, 0.5e-3, 0.0, 0.0);
    assert!(
        c.is_none_or(|c| tightness(&p, 0.5e-3, &c, 0.0) >= 1.0),
        "{c:?}"
    );
}
