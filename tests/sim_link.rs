//! The link model: no packet arrives before it was sent, delays follow
//! their distribution, and the named profiles measure as they are defined.

use proptest::prelude::*;
use vl_core::Named;
use vl_sim::{Distribution, Link, LinkModel, Loss, Profile, measure};

fn model() -> impl Strategy<Value = LinkModel> {
    let distribution = prop_oneof![
        Just(Distribution::Uniform),
        Just(Distribution::Normal),
        Just(Distribution::Pareto),
        Just(Distribution::ParetoNormal)
    ];
    let loss = prop_oneof![
        Just(Loss::None),
        (0.0f64..0.5, 0.0f64..0.9).prop_map(|(p, correlation)| Loss::Random { p, correlation }),
        (0.0f64..0.2, 0.05f64..1.0, 0.0f64..=1.0, 0.0f64..0.1).prop_map(
            |(p, r, bad_loss, good_loss)| Loss::GilbertElliott {
                p,
                r,
                bad_loss,
                good_loss
            }
        ),
    ];
    (
        0.0f64..300.0,
        0.0f64..100.0,
        0.0f64..0.95,
        distribution,
        loss,
        0.0f64..0.2,
        0.0f64..0.2,
        proptest::option::of(1000.0f64..1e6),
    )
        .prop_map(
            |(
                delay_ms,
                jitter_ms,
                correlation,
                distribution,
                loss,
                duplicate,
                reorder,
                rate_bytes_s,
            )| LinkModel {
                delay_ms,
                jitter_ms,
                correlation,
                distribution,
                loss,
                duplicate,
                reorder,
                rate_bytes_s,
                disconnects: vec![(500.0, 700.0)],
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn nothing_arrives_before_it_was_sent(model in model(), seed in any::<u64>()) {
        let mut link = Link::new(model, seed);
        for i in 0..500 {
            let sent = i as f64 * 5.0;
            let copies = link.send(sent, 200);
            prop_assert!(copies.len() <= 2);
            prop_assert!(copies.iter().all(|&at| at >= sent), "{:?} before {}", copies, sent);
            if (500.0..700.0).contains(&sent) {
                prop_assert!(copies.is_empty(), "sent during a disconnect");
            }
        }
    }

    #[test]
    fn uniform_delays_stay_in_their_band(mean in 10.0f64..200.0, jitter in 0.0f64..10.0, rho in 0.0f64..0.9, seed in any::<u64>()) {
        let model = LinkModel { delay_ms: mean, jitter_ms: jitter, correlation: rho, ..LinkModel::profile(Profile::Lan) };
        let mut link = Link::new(model, seed);
        for i in 0..1000 {
            let sent = i as f64;
            for at in link.send(sent, 100) {
                let d = at - sent;
                prop_assert!(d >= mean - jitter - 1e-9 && d <= mean + jitter + 1e-9);
            }
        }
    }
}

/// |got − want| within `tolerance` of `want`.
fn close(got: f64, want: f64, tolerance: f64) -> bool {
    (got - want).abs() <= tolerance * want.abs()
}

#[test]
fn named_profiles_measure_as_defined() {
    for &name in Profile::ALL {
        let model = LinkModel::profile(name);
        let stats = measure(&mut Link::new(model.clone(), 7), 100_000, 10.0, 100);
        assert!(
            close(stats.delay_mean_ms, model.expected_delay(), 0.05),
            "{name}: mean {}",
            stats.delay_mean_ms
        );
        assert!(
            close(stats.jitter_ms, model.expected_jitter(), 0.05),
            "{name}: jitter {}",
            stats.jitter_ms
        );
        // Losses are rare events: at 0.1 % a run of 100,000 packets sees about
        // 100 of them, so the tolerance is four binomial deviations, at least 5 %.
        let p = model.expected_loss();
        if p > 0.0 {
            let bursts = 100_000.0 * p / model.expected_burst();
            let tolerance = (4.0 / bursts.sqrt()).max(0.05);
            assert!(
                close(stats.loss_rate, p, tolerance),
                "{name}: loss {} vs {p}",
                stats.loss_rate
            );
            assert!(
                close(stats.mean_loss_burst, model.expected_burst(), tolerance),
                "{name}: burst {}",
                stats.mean_loss_burst
            );
        } else {
            assert_eq!(stats.loss_rate, 0.0);
        }
    }
}
