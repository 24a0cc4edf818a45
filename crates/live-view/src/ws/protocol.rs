//! The Foxglove WebSocket protocol v1 messages the live view speaks
//! (<https://github.com/foxglove/ws-protocol/blob/main/docs/spec.md>): the server's JSON
//! messages and binary frames, the client's requests parsed with every field checked.

use serde_json::{json, Value};

/// Subprotocols served: the protocol's own name (the official TypeScript client, Foxglove's
/// app) and the Foxglove SDK's name for the same protocol with inline schemas.
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];

/// Binary opcodes.
pub mod opcode {
    /// Server: message data (subscription id, log time, payload).
    pub const MESSAGE_DATA: u8 = 0x01;
    /// Client: service call request (service id, call id, encoding, payload).
    pub const SERVICE_CALL_REQUEST: u8 = 0x02;
    /// Server: service call response (same layout).
    pub const SERVICE_CALL_RESPONSE: u8 = 0x03;
}

/// A parameter value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParameterValue {
    /// A number sent as `float64`.
    Float64(f64),
    /// An integer.
    Integer(i64),
    /// A string.
    String(String),
}

/// A named parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Its name.
    pub name: String,
    /// Its value (None: unset).
    pub value: Option<ParameterValue>,
}

impl Parameter {
    /// A `float64` parameter.
    pub fn float64(name: &str, v: f64) -> Self {
        Parameter {
            name: name.into(),
            value: Some(ParameterValue::Float64(v)),
        }
    }
    /// An integer parameter.
    pub fn integer(name: &str, v: i64) -> Self {
        Parameter {
            name: name.into(),
            value: Some(ParameterValue::Integer(v)),
        }
    }
    /// A string parameter.
    pub fn string(name: &str, v: impl Into<String>) -> Self {
        Parameter {
            name: name.into(),
            value: Some(ParameterValue::String(v.into())),
        }
    }

    fn to_json(&self) -> Value {
        match &self.value {
            Some(ParameterValue::Float64(v)) => {
                json!({"name": self.name, "value": v, "type": "float64"})
            }
            Some(ParameterValue::Integer(v)) => json!({"name": self.name, "value": v}),
            Some(ParameterValue::String(v)) => json!({"name": self.name, "value": v}),
            None => json!({"name": self.name}),
        }
    }

    /// A parameter of a `setParameters` request (numbers typed `float64` or non-integral
    /// are floats; other types are kept unset, which the view treats as "not settable").
    fn from_json(v: &Value) -> Option<Self> {
        let name = v.get("name")?.as_str()?.to_owned();
        let float = v.get("type").and_then(Value::as_str) == Some("float64");
        let value = match v.get("value") {
            Some(Value::Number(n)) if !float && n.is_i64() => {
                n.as_i64().map(ParameterValue::Integer)
            }
            Some(Value::Number(n)) => n.as_f64().map(ParameterValue::Float64),
            Some(Value::String(s)) => Some(ParameterValue::String(s.clone())),
            _ => None,
        };
        Some(Parameter { name, value })
    }
}

/// `parameterValues`, answering request `id` if given.
pub fn parameter_values(params: &[Parameter], id: Option<&str>) -> String {
    let mut m = json!({
        "op": "parameterValues",
        "parameters": params.iter().map(Parameter::to_json).collect::<Vec<_>>(),
    });
    if let Some(id) = id {
        m["id"] = json!(id);
    }
    m.to_string()
}

/// `status` (0 info, 1 warning, 2 error).
pub fn status(level: u8, message: &str) -> String {
    json!({"op": "status", "level": level, "message": message}).to_string()
}

/// `serviceCallFailure`.
pub fn service_call_failure(service_id: u32, call_id: u32, message: &str) -> String {
    json!({"op": "serviceCallFailure", "serviceId": service_id, "callId": call_id, "message": message})
        .to_string()
}

/// A message data frame.
pub fn message_data(subscription: u32, log_time_ns: u64, payload: &[u8]) -> Vec<u8> {
    let mut b = Vec::with_capacity(13 + payload.len());
    b.push(opcode::MESSAGE_DATA);
    b.extend_from_slice(&subscription.to_le_bytes());
    b.extend_from_slice(&log_time_ns.to_le_bytes());
    b.extend_from_slice(payload);
    b
}

/// A service call response frame.
pub fn service_call_response(
    service_id: u32,
    call_id: u32,
    encoding: &str,
    payload: &[u8],
) -> Vec<u8> {
    let mut b = Vec::with_capacity(13 + encoding.len() + payload.len());
    b.push(opcode::SERVICE_CALL_RESPONSE);
    b.extend_from_slice(&service_id.to_le_bytes());
    b.extend_from_slice(&call_id.to_le_bytes());
    b.extend_from_slice(&(encoding.len() as u32).to_le_bytes());
    b.extend_from_slice(encoding.as_bytes());
    b.extend_from_slice(payload);
    b
}

/// What a client asked for.
#[derive(Debug, PartialEq)]
pub enum Request {
    /// `subscribe`: (subscription id, channel id) pairs.
    Subscribe(Vec<(u32, u32)>),
    /// `unsubscribe`: subscription ids.
    Unsubscribe(Vec<u32>),
    /// `getParameters`: names (empty: all), request id.
    GetParameters(Vec<String>, Option<String>),
    /// `setParameters`: values, request id.
    SetParameters(Vec<Parameter>, Option<String>),
    /// `subscribeParameterUpdates` (empty: all).
    SubscribeParameters(Vec<String>),
    /// `unsubscribeParameterUpdates` (empty: all).
    UnsubscribeParameters(Vec<String>),
    /// A service call: service id, call id, encoding, payload.
    CallService(u32, u32, String, Vec<u8>),
    /// Anything else (named for the status reply).
    Unsupported(String),
}

/// A text frame from a client.
pub fn parse_text(text: &str) -> Request {
    let Ok(v) = serde_json::from_str::<Value>(text) else {
        return Request::Unsupported("a text frame that is not JSON".into());
    };
    let op = v.get("op").and_then(Value::as_str).unwrap_or("");
    let id = v.get("id").and_then(Value::as_str).map(str::to_owned);
    let names = || -> Vec<String> {
        v.get("parameterNames")
            .and_then(Value::as_array)
            .map(|a| {
                a.iter()
                    .filter_map(|n| n.as_str().map(str::to_owned))
                    .collect()
            })
            .unwrap_or_default()
    };
    let u32_of = |x: &Value| x.as_u64().and_then(|n| u32::try_from(n).ok());
    match op {
        "subscribe" => Request::Subscribe(
            v.get("subscriptions")
                .and_then(Value::as_array)
                .map(|a| {
                    a.iter()
                        .filter_map(|s| Some((u32_of(s.get("id")?)?, u32_of(s.get("channelId")?)?)))
                        .collect()
                })
                .unwrap_or_default(),
        ),
        "unsubscribe" => Request::Unsubscribe(
            v.get("subscriptionIds")
                .and_then(Value::as_array)
                .map(|a| a.iter().filter_map(u32_of).collect())
                .unwrap_or_default(),
        ),
        "getParameters" => Request::GetParameters(names(), id),
        "setParameters" => Request::SetParameters(
            v.get("parameters")
                .and_then(Value::as_array)
                .map(|a| a.iter().filter_map(Parameter::from_json).collect())
                .unwrap_or_default(),
            id,
        ),
        "subscribeParameterUpdates" => Request::SubscribeParameters(names()),
        "unsubscribeParameterUpdates" => Request::UnsubscribeParameters(names()),
        other => Request::Unsupported(format!("op {other:?}")),
    }
}

/// A binary frame from a client.
pub fn parse_binary(b: &[u8]) -> Request {
    let u32_at = |at: usize| {
        b.get(at..at + 4)
            .map(|s| u32::from_le_bytes(s.try_into().expect("4")))
    };
    if b.first() != Some(&opcode::SERVICE_CALL_REQUEST) {
        return Request::Unsupported(format!("binary opcode {:?}", b.first()));
    }
    let parsed = (|| {
        let (service, call, n) = (u32_at(1)?, u32_at(5)?, u32_at(9)? as usize);
        let encoding = std::str::from_utf8(b.get(13..13 + n)?).ok()?.to_owned();
        Some(Request::CallService(
            service,
            call,
            encoding,
            b[13 + n..].to_vec(),
        ))
    })();
    parsed.unwrap_or_else(|| Request::Unsupported("a malformed service call".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_with_their_fields() {
        assert_eq!(
            parse_text(r#"{"op":"subscribe","subscriptions":[{"id":7,"channelId":1}]}"#),
            Request::Subscribe(vec![(7, 1)])
        );
        assert_eq!(
            parse_text(
                r#"{"op":"setParameters","id":"g","parameters":[{"name":"gain_scale","value":1,"type":"float64"}]}"#
            ),
            Request::SetParameters(
                vec![Parameter::float64("gain_scale", 1.0)],
                Some("g".into())
            )
        );
        assert_eq!(
            parse_text(r#"{"op":"setParameters","parameters":[{"name":"n","value":2}]}"#),
            Request::SetParameters(vec![Parameter::integer("n", 2)], None)
        );
        let call = service_call_response(3, 9, "json", b"{}");
        let mut request = call.clone();
        request[0] = opcode::SERVICE_CALL_REQUEST;
        assert_eq!(
            parse_binary(&request),
            Request::CallService(3, 9, "json".into(), b"{}".to_vec())
        );
        assert!(matches!(
            parse_binary(&request[..10]),
            Request::Unsupported(_)
        ));
        assert!(matches!(parse_text("[1"), Request::Unsupported(_)));
    }
}
