"""The small lead-follow idm campaign the farm tests run as a real CLI process (a few
seconds on the local executor): one place for its TOML, so tests differ only in what
they say they change."""


def lead_follow_toml(*, delta_min=2.0, epsilon=0.01, horizon=30, executor="local", farm_extra="",
                     quantify_extra="") -> str:
    return f"""
[scenario]
name = "lead-follow"
sv_policy = "idm"
[actions]
mode = "uniform"
[quantify]
delta0 = 4.0
delta_min = {delta_min!r}
epsilon = {epsilon!r}
horizon = {horizon}
{quantify_extra}[farm]
executor = "{executor}"
batch_size = 256
{farm_extra}"""
