use sim_core::{
    config::EnvConfig,
    env::Env,
    expert::Expert,
    scenario::{EvalRoute, Scenario},
    town::Town,
};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let route = EvalRoute::from_name(&args[1]).unwrap();
    let seed: u64 = args[2].parse().unwrap();
    let town = Town::default_town();
    let mut env = Env::new(town.clone(), EnvConfig::default()).unwrap();
    env.reset(seed, Scenario::Eval(route)).unwrap();
    let ex = Expert::default();
    for t in 0..300 {
        let a = ex.act(&env);
        let r = env.step(a).unwrap();
        if t % 10 == 0 || r.terminated {
            println!(
                "t={t} s={:.1} v={:.1} hold={:?} next={:?} a={:?}",
                env.tracking.s,
                env.ego.speed,
                env.ego_hold(),
                env.next_connector(),
                a
            );
            for (i, c) in env.traffic.cars.iter().enumerate() {
                if c.pos.distance(env.ego.pos) < 40.0 {
                    println!(
                        "   car {i} lane {} s {:.1} v {:.1} hold {:?} next {:?} req {:?} pos {:?}",
                        c.lane, c.s, c.speed, c.hold, c.next, c.requested_at, c.pos
                    );
                }
            }
        }
        if r.terminated || r.truncated {
            break;
        }
    }
}
